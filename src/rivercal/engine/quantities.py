"""The settable quantities of a compiled case, in one table: names, what they set, units and bounds.

:func:`settable_table` builds the table once from the compiled network (and the case's controllers).
:meth:`Simulator.parameter_arrays <rivercal.engine.Simulator.parameter_arrays>` sets parameters through it
(:func:`quantity_arrays`), and the embedded model declares it as its quantities
(:attr:`rivercal.models.EmbeddedModel.quantities`), so that a name that one accepts the other declares, with the
same bounds. :func:`parse_target` splits a name into its kind and id, :func:`default_values` gives the case's
values and :func:`quantities_table` shows them with what a model declares of them
(:meth:`Simulator.quantities_frame <rivercal.engine.Simulator.quantities_frame>`).

- ``weir:<id>.crest_level`` — crest level of a weir, m AD (a weir driven by a controller is marked
  ``controlled``: its controller sets its crest);
- ``friction:global`` — the friction value of every branch that inherits the case's friction (unit of the
  case's friction law), present when some branch inherits it;
- ``friction:branch:<id>`` — the friction value of one branch (unit of its law);
- ``friction:group:<id>`` — the value of a friction group (``[[friction_groups]]``, unit of its law);
- ``friction:scale`` — a factor (-) on the conveyance of every channel friction coefficient, present when no
  link uses White-Colebrook friction (a factor on its coefficient does not scale its conveyance);
- ``friction:factor:<id>`` — a factor (-) declared in ``[[friction_factors]]`` on the conveyance of the channel
  friction of a set of branches and friction groups (:class:`rivercal.case.schema.FrictionFactor`): their
  coefficients move together and keep their ratios (n divided by the factor, k_s and C multiplied by it). Its
  slots are those of the channel links on the listed branches (:func:`rivercal.engine.compile.own_friction_slots`
  gives the links that take a group's shared value a slot per branch first) and every slot of the listed groups;
  bounds :data:`FACTOR_RANGE`;
- ``control:<id>.<quantity>`` — the quantities of the case's controllers (:mod:`rivercal.engine.controllers`).

Friction bounds are the plausible ranges of :data:`rivercal.network.FRICTION_RANGES`; crests lie within
±:data:`rivercal.network.MAX_LEVEL` m AD.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NoReturn

import numpy as np
import pandas as pd

from rivercal.engine.compile import FRICTION_CODES, CompiledNetwork
from rivercal.engine.kernels.codes import LINK_CHANNEL
from rivercal.network import FRICTION_RANGES, MAX_LEVEL

__all__ = [
    "FACTOR_RANGE",
    "SCALE_RANGE",
    "FactorProblem",
    "Settable",
    "default_values",
    "factor_slots",
    "mixed_group_problem",
    "parse_target",
    "quantities_table",
    "quantity_arrays",
    "settable_table",
    "unknown_quantity",
]

#: Bounds of ``friction:scale`` (-).
SCALE_RANGE = (0.05, 20.0)
#: Bounds of ``friction:factor:<id>`` (-). A factor scales coefficients that someone already chose branch by branch
#: (surveyed, taken from tables or calibrated before), keeping their ratios: it corrects their common level, not the
#: pattern. A factor of 5 turns a Manning n of 0.035 into 0.007 (a smooth concrete channel) or 0.175 (a channel
#: choked with vegetation), which spans the plausible range of one channel type several times over; a wider range
#: only lets an optimiser wander where the scaled values leave every plausible range
#: (:data:`rivercal.network.FRICTION_RANGES`). Narrower than ``friction:scale``'s, whose reach is the whole model.
FACTOR_RANGE = (0.2, 5.0)

_LAWS = {code: name for name, code in FRICTION_CODES.items()}
#: The order in which :func:`quantity_arrays` applies the kinds of :func:`parse_target` (others: 1).
_ORDER = {"friction": 0, "factor": 2, "scale": 3}
_MANNING = FRICTION_CODES["manning"]


@dataclass(frozen=True)
class Settable:
    """One settable quantity of a compiled case (module docstring).

    Attributes
    ----------
    name
        The name parameters target.
    kind
        ``weir``, ``friction`` (global), ``branch``, ``group``, ``factor``, ``scale`` or ``control``.
    slots
        What it sets: the weir's index (``weir``), the friction slots (``friction``, ``branch``, ``group``) or
        the friction slots it scales (``factor``); empty for ``scale`` and ``control``.
    unit, low, high
        Unit and bounds of the value.
    description
        One line for users.
    controlled
        A weir whose crest a controller sets (not settable through the model contract).
    """

    name: str
    kind: str
    slots: tuple[int, ...]
    unit: str
    low: float | None
    high: float | None
    description: str
    controlled: bool = False


class FactorProblem(ValueError):
    """A friction factor of the case that the compiled network cannot honour.

    ``index`` is the factor's position in ``[[friction_factors]]``, ``reason`` what is wrong.
    """

    def __init__(self, index: int, reason: str):
        self.index = index
        self.reason = reason
        super().__init__(f"friction_factors[{index}]: {reason}")


def factor_slots(compiled: CompiledNetwork, factor: Any) -> tuple[int, ...]:
    """The friction slots that a friction factor (:class:`rivercal.case.schema.FrictionFactor`) scales.

    The slots of the channel links on its branches and every slot of its groups (their own value, their values on
    particular branches and the slots split off per branch by :func:`rivercal.engine.compile.own_friction_slots`).

    Raises
    ------
    ValueError
        When a link on one of its branches still conveys with a group's value that other branches share (the
        network was compiled without :func:`~rivercal.engine.compile.own_friction_slots`), when it scales no
        channel link, or when a slot it scales uses White-Colebrook friction (a factor on the roughness height
        does not scale the conveyance).
    """
    c, a = compiled, compiled.arrays
    keys = c.friction_slots
    laws = {code: name for name, code in FRICTION_CODES.items()}
    channel = a.lk_type == LINK_CHANNEL
    on_listed = channel & np.isin(np.asarray(c.link_branch, dtype=object), list(factor.branches))
    slots = set(np.unique(a.lk_fric[on_listed]).tolist())
    for slot in sorted(slots):
        if keys[slot][0] == "group" and len(keys[slot]) == 2:
            raise ValueError(f"friction factor {factor.id!r}: a link of one of its branches conveys with friction "
                             f"group {keys[slot][1]!r}'s value, which other branches share; compile the network "
                             "with own_friction_slots")
    groups = set(factor.groups)
    slots.update(i for i, key in enumerate(keys) if key[0] in ("group", "split") and key[1] in groups)
    used = set(np.unique(a.lk_fric[channel]).tolist())
    if not slots & used:
        raise ValueError(f"friction factor {factor.id!r} scales the friction of no channel link")
    for slot in sorted(slots & used):
        if laws[int(a.fr_type[slot])] == "white-colebrook":
            what = f"friction group {keys[slot][1]!r}" if keys[slot][0] != "branch" else f"branch {keys[slot][1]!r}"
            raise ValueError(f"friction factor {factor.id!r}: {what} uses White-Colebrook friction, whose conveyance "
                             "a factor on the roughness height does not scale")
    return tuple(sorted(slots))


def settable_table(compiled: CompiledNetwork, friction_type: str, controls: Any = None,
                   factors: Any = ()) -> dict[str, Settable]:
    """Every settable quantity of a compiled case by name (module docstring).

    Parameters
    ----------
    compiled
        The compiled network.
    friction_type
        The case's friction law (of the branches that inherit it).
    controls
        The case's controllers (:class:`rivercal.engine.controllers.Controls`), or None.
    factors
        The case's friction factors (:class:`rivercal.case.schema.FrictionFactor`).

    Raises
    ------
    FactorProblem
        For a factor that :func:`factor_slots` refuses, or one that scales a slot another factor scales too (a
        branch of one factor whose links convey with a group of another).
    """
    c = compiled
    laws = {code: name for name, code in FRICTION_CODES.items()}
    controlled = {spec.weir for spec in controls.specs} if controls else set()
    out: dict[str, Settable] = {}
    for i, w in enumerate(c.weir_ids):
        name = f"weir:{w}.crest_level"
        out[name] = Settable(name, "weir", (i,), "m AD", -MAX_LEVEL, MAX_LEVEL, f"crest level of weir {w}",
                             controlled=w in controlled)
    branch_pos = {b: i for i, b in enumerate(c.branch_ids)}
    if c.branch_inherits:
        low, high, unit = FRICTION_RANGES[friction_type]
        out["friction:global"] = Settable("friction:global", "friction",
                                          tuple(branch_pos[b] for b in c.branch_inherits), unit, low, high,
                                          f"{friction_type} friction of the branches that inherit the case's friction")
    for i, b in enumerate(c.branch_ids):
        law = laws[int(c.arrays.fr_type[i])]
        low, high, unit = FRICTION_RANGES[law]
        name = f"friction:branch:{b}"
        out[name] = Settable(name, "branch", (i,), unit, low, high, f"{law} friction of branch {b}")
    for i, key in enumerate(c.friction_slots):
        if key[0] == "group" and len(key) == 2 and key[1] not in c.friction_mixed:  # see mixed_group_problem
            law = laws[int(c.arrays.fr_type[i])]
            low, high, unit = FRICTION_RANGES[law]
            name = f"friction:group:{key[1]}"
            split = tuple(j for j, other in enumerate(c.friction_slots) if other[0] == "split" and other[1] == key[1])
            out[name] = Settable(name, "group", (i, *split), unit, low, high,
                                 f"{law} friction of friction group {key[1]}")
    used = set(np.unique(c.arrays.lk_fric).tolist())  # the friction slots some link uses
    if all(laws[int(code)] != "white-colebrook" for i, code in enumerate(c.arrays.fr_type) if i in used):
        out["friction:scale"] = Settable("friction:scale", "scale", (), "-", *SCALE_RANGE,
                                         "factor on the conveyance of every channel friction coefficient")
    scaled_by: dict[int, str] = {}
    for index, factor in enumerate(factors):
        name = f"friction:factor:{factor.id}"
        try:
            slots = factor_slots(c, factor)
        except ValueError as exc:
            raise FactorProblem(index, str(exc)) from None
        for slot in slots:
            if slot in scaled_by:
                key = c.friction_slots[slot]
                what = f"branch {key[1]!r}" if key[0] == "branch" else \
                    f"friction group {key[1]!r}" + (f" on branch {key[2]!r}" if len(key) > 2 else "")
                raise FactorProblem(index, f"friction factor {factor.id!r} scales the friction of {what}, which "
                                    f"friction factor {scaled_by[slot]!r} scales too; a coefficient belongs to one "
                                    "factor at most")
            scaled_by[slot] = factor.id
        listed = [f"branch{'es' if len(factor.branches) > 1 else ''} {', '.join(factor.branches)}"] \
            if factor.branches else []
        listed += [f"group{'s' if len(factor.groups) > 1 else ''} {', '.join(factor.groups)}"] if factor.groups else []
        out[name] = Settable(name, "factor", slots, "-", *FACTOR_RANGE,
                             f"factor on the friction conveyance of {' and '.join(listed)} (n / factor, k_s and C "
                             "times the factor)")
    for name, (unit, low, high, text) in (controls.describe() if controls else {}).items():
        out[name] = Settable(name, "control", (), unit, low, high, text)
    return out


def parse_target(target: str) -> tuple[str, str]:
    """Split a target string into (kind, id).

    The kinds are ``("weir", id)``, ``("friction", "global")``, ``("branch", id)``, ``("group", id)``,
    ``("factor", id)`` and ``("scale", "all")``.

    Raises
    ------
    KeyError
        For a malformed target.
    """
    if target.startswith("weir:") and target.endswith(".crest_level"):
        return "weir", target[len("weir:") : -len(".crest_level")]
    if target == "friction:global":
        return "friction", "global"
    if target.startswith("friction:branch:"):
        return "branch", target[len("friction:branch:") :]
    if target.startswith("friction:group:"):
        return "group", target[len("friction:group:") :]
    if target.startswith("friction:factor:"):
        return "factor", target[len("friction:factor:") :]
    if target == "friction:scale":
        return "scale", "all"
    raise KeyError(
        f"unknown model quantity {target!r}; expected 'weir:<id>.crest_level', 'friction:global', "
        "'friction:branch:<id>', 'friction:group:<id>', 'friction:scale', 'friction:factor:<id>' or "
        "'control:<id>.<quantity>'"
    )


def default_values(compiled: CompiledNetwork, global_friction: float | None, controls: Any = None) -> dict[str, float]:
    """The settable quantities' values in the compiled case (targets → values, in their units).

    ``global_friction`` is the case's friction value (of the branches that inherit it), ``controls`` the case's
    controllers (:class:`rivercal.engine.controllers.Controls`) or None.
    """
    c = compiled
    out = {f"weir:{w}.crest_level": float(v) for w, v in zip(c.weir_ids, c.crest_levels, strict=True)}
    if c.branch_inherits:
        out["friction:global"] = float(global_friction)
    for b, v in zip(c.branch_ids, c.friction_values, strict=False):
        if b not in c.branch_inherits:
            out[f"friction:branch:{b}"] = float(v)
    for key, v in zip(c.friction_slots, c.friction_values, strict=True):
        if key[0] == "group" and len(key) == 2 and key[1] not in c.friction_mixed:
            out[f"friction:group:{key[1]}"] = float(v)
    if controls:
        out.update(controls.default_parameters())
    return out


def quantity_arrays(compiled: CompiledNetwork, table: Mapping[str, Settable], parameters: Mapping[str, float] | None,
                    *, case_name: str, profiles: Sequence[Any]) -> tuple[np.ndarray, np.ndarray]:
    """Crest levels (m AD, per weir) and friction values (per friction slot) for a set of targets.

    What :meth:`Simulator.parameter_arrays <rivercal.engine.Simulator.parameter_arrays>` computes (the order in
    which values compose is told there): ``table`` is the case's :func:`settable_table`, ``case_name`` and
    ``profiles`` (the network's cross-section profiles) word the error for a name that is not in it
    (:func:`unknown_quantity`). The targets of controllers (``control:``) are left to the controllers.
    """
    c = compiled
    crest = c.crest_levels.copy()
    fric = c.friction_values.copy()
    # Global first, so that a branch-specific value given in the same call wins; then the factors; the scale last.
    items = sorted((parameters or {}).items(), key=lambda kv: _ORDER.get(parse_target(kv[0])[0], 1)
                   if not kv[0].startswith("control:") else 1)
    for target, value in items:
        if target.startswith("control:"):
            continue  # control_values
        entry = table.get(target)
        if entry is None or entry.kind == "control":
            unknown_quantity(target, compiled, case_name, profiles)
        value = float(value)
        if not np.isfinite(value):
            raise ValueError(f"{target}: value {value} is not finite")
        if entry.kind in ("scale", "factor"):
            if not entry.low <= value <= entry.high:
                raise ValueError(f"{target}: factor {value:g} is outside {entry.low:g}-{entry.high:g}")
            slots = range(fric.size) if entry.kind == "scale" else entry.slots
            for i in slots:
                fric[i] = fric[i] / value if int(c.arrays.fr_type[i]) == _MANNING else fric[i] * value
            continue
        if entry.kind == "weir":
            if abs(value) > MAX_LEVEL:
                raise ValueError(f"{target}: crest level {value:g} m AD is outside ±{MAX_LEVEL:g} m AD")
            crest[entry.slots[0]] = value
            continue
        for slot in entry.slots:  # friction: global, branch or group
            law = _LAWS[int(c.arrays.fr_type[slot])]
            low, high, unit = FRICTION_RANGES[law]
            if not low <= value <= high:
                raise ValueError(f"{target}: {law} value {value:g} {unit} is outside the plausible range "
                                 f"{low:g}-{high:g} {unit}")
            fric[slot] = value
    return crest, fric


def unknown_quantity(target: str, compiled: CompiledNetwork, case_name: str, profiles: Sequence[Any]) -> NoReturn:
    """KeyError saying why ``target`` is not a settable quantity of case ``case_name``.

    ``profiles`` are the case network's cross-section profiles (for :func:`mixed_group_problem`).
    """
    kind, ident = parse_target(target)  # a malformed name: KeyError naming the forms
    c = compiled
    if kind == "scale":
        raise KeyError(f"{target}: case {case_name!r} has White-Colebrook friction, whose "
                       "conveyance a factor on the coefficient does not scale")
    if kind == "factor":
        raise KeyError(f"{target}: case {case_name!r} declares no friction factor {ident!r} "
                       "(declare it in [[friction_factors]] with the branches and groups it scales)")
    if kind == "group":
        if ident in c.friction_mixed:
            raise KeyError(mixed_group_problem(target, ident, compiled, profiles))
        raise KeyError(f"{target}: no friction group {ident!r} in case {case_name!r}")
    if kind == "weir":
        raise KeyError(f"{target}: no weir {ident!r} in case {case_name!r}")
    if kind == "friction" and not c.branch_inherits:
        raise KeyError(f"{target}: every branch of case {case_name!r} has its own friction")
    raise KeyError(f"{target}: no branch {ident!r} in case {case_name!r}")


def mixed_group_problem(target: str, group: str, compiled: CompiledNetwork, profiles: Sequence[Any]) -> str:
    """Why ``target``, the value of friction group ``group``, cannot be set on this network (a message).

    See :meth:`Simulator.mixed_group_problem <rivercal.engine.Simulator.mixed_group_problem>`; ``profiles`` are the
    case network's cross-section profiles.
    """
    profile = next(p for p in profiles if p.id == compiled.friction_mixed[group])
    groups = list(dict.fromkeys(profile.friction))
    effect = ("would scale the conveyance of its other sections (" + ", ".join(g for g in groups if g != group)
              + ") as well" if groups[0] == group else "would not change the conveyance of the links that use it, "
              f"which is held relative to its first section's group {groups[0]!r}")
    return (f"{target}: friction group {group!r} shares profile {profile.id!r} with friction group(s) "
            f"{', '.join(repr(g) for g in groups if g != group)}; a change of {group!r} alone {effect}, so it is "
            "not a calibration target of this case (calibrate friction:scale, which scales every section, or "
            "give the profile's sections one group)")


def quantities_table(values: Mapping[str, float], declared: Mapping[str, Any],
                     branch_inherits: Sequence[str]) -> pd.DataFrame:
    """The model quantities as a table, one row per quantity name.

    What :meth:`Simulator.quantities_frame <rivercal.engine.Simulator.quantities_frame>` shows: ``values`` are the
    case's values (:func:`default_values`), ``declared`` the quantities a model declares
    (:class:`rivercal.models.contract.Quantity`: unit, bounds, description; may be empty) and ``branch_inherits``
    the branches that inherit the global friction.
    """
    inherited = {f"friction:branch:{b}" for b in branch_inherits}
    rows = []
    for name in sorted({*values, *declared}):
        q = declared.get(name)
        value, note = values.get(name, np.nan), ""
        if name in inherited and "friction:global" in values:
            value, note = values["friction:global"], " (inherits friction:global)"
        elif name == "friction:scale" or name.startswith("friction:factor:"):
            value = 1.0
        rows.append({"quantity": name, "value": value, "unit": q.unit if q else "",
                     "min": _shown_bound(None if q is None else q.min, -np.inf),
                     "max": _shown_bound(None if q is None else q.max, np.inf),
                     "description": (q.description if q else "") + note})
    columns = ["quantity", "value", "unit", "min", "max", "description"]
    return pd.DataFrame(rows, columns=columns).set_index("quantity")


def _shown_bound(value: float | None, none: float) -> float:
    """A declared bound for a table: ``none`` (±inf) where there is none (None, or the stand-in ±MAX_LEVEL)."""
    if value is None or abs(float(value)) >= MAX_LEVEL:
        return none
    return float(value)
