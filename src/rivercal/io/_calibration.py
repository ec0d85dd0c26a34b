"""Calibration parameters an imported model gets, so that it can be calibrated as imported.

A model's files say nothing of what a water board wants to estimate; an import writes one parameter per
friction coefficient the channels use and one per constant weir crest, with bounds around the model's own value.
The user keeps, removes or adds (``case.toml`` ``[[parameters]]``).
"""

from __future__ import annotations

import re
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from rivercal.io.ledger import Ledger

__all__ = ["write_parameters"]


#: Bounds of an imported friction parameter, as factors on the model's value (smoother, rougher): k_s and C
#: rise with smoothness, Manning's n and a roughness height with roughness.
_FRICTION_FACTORS = {"strickler": (0.5, 2.5), "chezy": (0.5, 2.5), "manning": (0.4, 2.0),
                     "white-colebrook": (0.1, 10.0)}
#: How far an imported crest parameter may move from the model's crest, m.
CREST_RANGE = 0.5


def write_parameters(case: dict, ledger: Ledger, *, parallel: Collection[str] = (),
                     pieces: Mapping[str, list[str]] | None = None) -> None:
    """``[[parameters]]`` so that the case can be calibrated as imported.

    One per friction coefficient the channels use — ``FA`` for the global friction (D-Flow FM's default
    group ``Main``, or the MDU's uniform friction) when a channel takes it, ``F_<branch>`` for a branch with
    its own friction in group ``Main``, ``F_<group>`` for every other friction group that a channel profile
    refers to alone; groups that share a profile (a main channel and its floodplains) are scaled together by
    ``F_scale`` (``friction:scale``, a factor on the conveyance of every friction coefficient, 0.5-2) — and one per
    weir whose crest is a constant in the files (``W_<weir>``; a crest that follows a series or real-time control
    is set by that, not calibrated). Bounds: the model's value times 0.5-2.5 for k_s and C, 0.4-2 for Manning's n,
    0.1-10 for a White-Colebrook roughness height, within the plausible range of the law; a crest ±0.5 m, never
    below the bed. The initial value is the model's own.

    Parameters
    ----------
    case
        The case being written (its ``parameters`` are set).
    ledger
        The import's account: each parameter is listed, and a friction value outside its law's range is warned of.
    parallel
        Branches that carry one member of a compound structure (they take no parameter of their own).
    pieces
        Branches cut into pieces (a compound structure's stretch): original id → the pieces' ids, which share
        the original's friction parameter.
    """
    pieces = pieces or {}
    from rivercal.network import FRICTION_RANGES

    params: list[dict] = []
    taken: set[str] = set()

    def name(prefix: str, ident: str) -> str:
        base = (prefix + re.sub(r"[^A-Za-z0-9_]", "_", ident))[:32]
        new, k = base, 2
        while new in taken:
            new = f"{base[:28]}_{k}"
            k += 1
        taken.add(new)
        return new

    def friction(pname: str, target: str, law: str, value: float, what: str) -> None:
        lo_f, hi_f = _FRICTION_FACTORS[law]
        lo_r, hi_r, unit = FRICTION_RANGES[law]
        lo, hi = max(value * lo_f, lo_r), min(value * hi_f, hi_r)
        if not lo <= value <= hi or not hi > lo:
            ledger.warn(f"no calibration parameter for {what}: its value {value:g} lies outside the plausible "
                            f"range of the {law} law")
            return
        params.append({"name": pname, "targets": [target], "min": _round(lo), "max": _round(hi),
                       "initial": value, "transform": "offset", "perturbation": _round(0.1 * value), "unit": unit})

    profiles = {p["id"]: p for p in case.get("profiles", [])}
    used_groups = {g for b in case["branches"] for cs in b["cross_sections"]
                   for g in profiles[cs["profile"]].get("friction", [])}
    # profiles without friction sections take the branch's own friction, else the global one
    plain = [b for b in case["branches"] if b["id"] not in parallel and any(
        not profiles[cs["profile"]].get("friction") for cs in b["cross_sections"])]
    glob = case.get("friction")
    if glob is not None and any("friction" not in b for b in plain):
        friction(name("", "FA"), "friction:global", glob["type"], float(glob["value"]), "the global friction")
    piece_of = {p: original for original, pieces in pieces.items() for p in pieces}
    done: set[str] = set()
    for b in plain:
        original = piece_of.get(b["id"], b["id"])
        if "friction" in b and original not in done:
            done.add(original)
            targets = [f"friction:branch:{p}" for p in pieces.get(original, [original])]
            friction(name("F_", original), targets[0], b["friction"]["type"], float(b["friction"]["value"]),
                     f"the friction of branch {original!r}")
            if params and params[-1]["targets"] == targets[:1]:
                params[-1]["targets"] = targets  # a branch cut for a compound: its pieces share its friction
    # a group that a profile names beside another group cannot be set alone (the profile conveys relative to its
    # first section's group): those groups are calibrated together, by a factor on every friction coefficient
    mixed = {g for p in profiles.values() if len(set(p.get("friction", []))) > 1 for g in p["friction"]}
    for g in case.get("friction_groups", []):
        if g["id"] in used_groups and g["id"] not in mixed:
            friction(name("F_", g["id"]), f"friction:group:{g['id']}", g["type"], float(g["value"]),
                     f"friction group {g['id']!r}")
    laws = {g["type"] for g in case.get("friction_groups", [])} | {b["friction"]["type"] for b in case["branches"]
                                                                   if "friction" in b}
    if mixed & used_groups:
        if "white-colebrook" in laws | ({glob["type"]} if glob else set()):
            ledger.warn("no calibration parameter for the friction groups " + ", ".join(sorted(mixed & used_groups))
                        + ": they share profiles, so they can only be scaled together, and a factor does not scale "
                        "White-Colebrook friction")
        else:
            params.append({"name": name("", "F_scale"), "targets": ["friction:scale"], "min": 0.5, "max": 2.0,
                           "initial": 1.0, "transform": "offset", "perturbation": 0.05, "unit": "-"})
    beds = {b["id"]: b for b in case["branches"]}
    for w in case.get("weirs", []):
        if "crest_series" in w:
            continue
        b = beds[w["branch"]]
        bed = float(np.interp(w["chainage"], [c["chainage"] for c in b["cross_sections"]],
                              [c["bed_level"] for c in b["cross_sections"]]))
        crest = float(w["crest_level"])
        lo, hi = max(crest - CREST_RANGE, bed), crest + CREST_RANGE
        params.append({"name": name("W_", w["id"]), "targets": [f"weir:{w['id']}.crest_level"], "min": _round(lo),
                       "max": _round(hi), "initial": crest, "transform": "offset", "perturbation": 0.05,
                       "unit": "m AD"})
    case["parameters"] = params
    for p in params:
        ledger.parameters.append(f"`{p['name']}`: {p['targets'][0]}, {p['min']:g} .. {p['max']:g} {p['unit']}, "
                                     f"initial {p['initial']:g}")


def _round(value: float) -> float:
    """A bound written with six significant digits (the exact value is not a property of the model)."""
    return float(f"{value:.6g}")
