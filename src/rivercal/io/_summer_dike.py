"""The summer dike of a tabulated (zw) profile as a case takes it, from D-Flow FM 1D or SOBEK 3.

Both kernels share the same summer-dike model (Deltares flow1d, ``GetSummerDikeFlow`` and
``GetSummerDikeTotal``): behind the dike a flow area and a total (storage) area fill from its crest over a
transition height along two parabolas; once the level has passed crest + transition, the storage behind the
dike empties on a falling limb down to its base level. The case's summer dike (``[profiles.summer_dike]``:
``crest``, ``flow_area``, ``total_area``, ``transition``, optional ``base``) does the same, with heights above
the profile's lowest level.
"""

from __future__ import annotations

__all__ = ["summer_dike"]


def summer_dike(*, crest: float, base: float, flow_area: float, total_area: float, bottom: float,
                transition: float, kernel: str) -> tuple[dict, list[str]]:
    """The case's summer dike of a profile, and notes on what was taken otherwise than the file gives it.

    Parameters
    ----------
    crest, base
        The dike's crest level and the base level its storage drains to, m above datum.
    flow_area, total_area
        The areas behind the dike that convey and that store water, m² (not negative; the caller leaves out a
        dike whose both areas are at most 1e-5 m², as both kernels do).
    bottom
        The profile's lowest level, m above datum.
    transition
        The height over which the areas fill above the crest, m.
    kernel
        The kernel whose behaviour the notes compare with (``D-Flow FM``, ``SOBEK 3``).
    """
    notes = []
    if total_area < flow_area:
        notes.append(f"summer dike: its total area {total_area:g} m² is below its flow area {flow_area:g} m²; the "
                     "case raises it to the flow area")
        total_area = flow_area
    if crest < bottom:
        notes.append(f"summer dike: its crest {crest:g} m lies below the lowest level of the table; taken at it")
        crest = bottom
    dike = {"crest": crest - bottom, "flow_area": flow_area, "total_area": total_area, "transition": transition}
    if crest < base < crest + transition:
        # the kernels drain it then by a steeper curve from crest + transition to the base and return to the rising
        # curve below the base, a jump of the stored volume; a base at or above crest + transition never leaves the
        # rising curve, which the crest as base gives exactly
        notes.append(f"summer dike: its base level {base:g} m lies between its crest {crest:g} m and crest + "
                     f"{transition:g} m: taken at the crest (the storage behind it fills and drains by the rising "
                     f"curve; {kernel} drains it by a steeper one down to the base level and then returns to the "
                     "rising one, a jump of the stored volume)")
    elif base < bottom:
        notes.append(f"summer dike: its base level {base:g} m lies below the lowest level of the table; taken at it")
        dike["base"] = 0.0
    elif base < crest:
        dike["base"] = base - bottom  # drains along the falling curve down to it, as the kernels do
    return dike, notes
