"""The settable quantities of a compiled case, in one table: names, what they set, units and bounds.

:func:`settable_table` builds the table once from the compiled network (and the case's controllers).
:meth:`Simulator.parameter_arrays <rivercal.engine.Simulator.parameter_arrays>` sets parameters through it, and
the embedded model declares it as its quantities (:attr:`rivercal.models.EmbeddedModel.quantities`), so that a
name that one accepts the other declares, with the same bounds.

- ``weir:<id>.crest_level`` — crest level of a weir, m AD (a weir driven by a controller is marked
  ``controlled``: its controller sets its crest);
- ``friction:global`` — the friction value of every branch that inherits the case's friction (unit of the
  case's friction law), present when some branch inherits it;
- ``friction:branch:<id>`` — the friction value of one branch (unit of its law);
- ``friction:group:<id>`` — the value of a friction group (``[[friction_groups]]``, unit of its law);
- ``friction:scale`` — a factor (-) on the conveyance of every channel friction coefficient, present when no
  link uses White-Colebrook friction (a factor on its coefficient does not scale its conveyance);
- ``control:<id>.<quantity>`` — the quantities of the case's controllers (:mod:`rivercal.engine.controllers`).

Friction bounds are the plausible ranges of :data:`rivercal.network.FRICTION_RANGES`; crests lie within
±:data:`rivercal.network.MAX_LEVEL` m AD.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rivercal.engine.compile import FRICTION_CODES, CompiledNetwork
from rivercal.network import FRICTION_RANGES, MAX_LEVEL

__all__ = ["SCALE_RANGE", "Settable", "settable_table"]

#: Bounds of ``friction:scale`` (-).
SCALE_RANGE = (0.05, 20.0)


@dataclass(frozen=True)
class Settable:
    """One settable quantity of a compiled case (module docstring).

    Attributes
    ----------
    name
        The name parameters target.
    kind
        ``weir``, ``friction`` (global), ``branch``, ``group``, ``scale`` or ``control``.
    slots
        What it sets: the weir's index (``weir``), the friction slots (``friction``, ``branch``, ``group``);
        empty for ``scale`` and ``control``.
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


def settable_table(compiled: CompiledNetwork, friction_type: str, controls: Any = None) -> dict[str, Settable]:
    """Every settable quantity of a compiled case by name (module docstring).

    Parameters
    ----------
    compiled
        The compiled network.
    friction_type
        The case's friction law (of the branches that inherit it).
    controls
        The case's controllers (:class:`rivercal.engine.controllers.Controls`), or None.
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
        if key[0] == "group" and len(key) == 2 and key[1] not in c.friction_mixed:  # see Simulator.mixed_group_problem
            law = laws[int(c.arrays.fr_type[i])]
            low, high, unit = FRICTION_RANGES[law]
            name = f"friction:group:{key[1]}"
            out[name] = Settable(name, "group", (i,), unit, low, high, f"{law} friction of friction group {key[1]}")
    used = set(np.unique(c.arrays.lk_fric).tolist())  # the friction slots some link uses
    if all(laws[int(code)] != "white-colebrook" for i, code in enumerate(c.arrays.fr_type) if i in used):
        out["friction:scale"] = Settable("friction:scale", "scale", (), "-", *SCALE_RANGE,
                                         "factor on the conveyance of every channel friction coefficient")
    for name, (unit, low, high, text) in (controls.describe() if controls else {}).items():
        out[name] = Settable(name, "control", (), unit, low, high, text)
    return out
