"""What went wrong where, when the time loop stops a run: the words of :class:`~rivercal.errors.EngineDivergedError`.

The time loop returns a status code with the step and the point (or link) at fault; :func:`divergence` turns
them into the time, the place and what to change, in the terms of the model's own network.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from rivercal.engine.kernels.codes import (
    DRY_TOLERANCE,
    FLICKER_DZ,
    MAX_HALVINGS,
    STATUS_DRY,
    STATUS_FLICKER,
    STATUS_VELOCITY,
)

if TYPE_CHECKING:
    from rivercal.engine.simulator import Simulator

__all__ = ["divergence"]


def divergence(sim: Simulator, status: int, step: int, index: int, z: np.ndarray, u: np.ndarray, start: pd.Timestamp,
               phase: str | None) -> tuple[str, str, str]:
    """When, where and what of a run of ``sim`` that the time loop stopped with ``status`` (the error's words).

    ``step`` and ``index`` are the time loop's step and point (or link) at fault, ``z`` (m AD) and ``u``
    (m/s) the run's levels and velocities as the loop left them.
    """
    when = (start + pd.Timedelta(seconds=(step + 1) * sim.dt)).isoformat()
    if phase:
        when += f" ({phase}, forcing held at its start value)"
    if status == STATUS_VELOCITY:
        return when, sim.compiled.link_label[index], (
            f"velocity {float(u[index]):.6g} m/s exceeds engine.max_velocity ({sim.settings.max_velocity} m/s)")
    where = sim.compiled.hp_label[index]
    smallest = sim.dt / 2**MAX_HALVINGS
    courant = _courant_near(sim, index, u)
    if status == STATUS_DRY:
        depth = float(z[index] - sim.compiled.arrays.hp_bed[index])
        return when, where, (
            f"the level falls {-depth:.3g} m below the bed (more than {DRY_TOLERANCE:g} m) even with the time "
            f"step divided into {2**MAX_HALVINGS} sub-steps of {smallest:.3g} s{courant}; the point loses more "
            "water per sub-step than it holds: reduce engine.dt (the longest step), or check the withdrawals and "
            "pumps there")
    if status == STATUS_FLICKER:
        return when, where, (
            f"the level there goes up and down by more than {FLICKER_DZ * 100:g} cm again and again, every few "
            f"steps, even with the time step divided into {2**MAX_HALVINGS} sub-steps "
            f"of {smallest:.3g} s{courant}: the flow there cannot be resolved; reduce engine.dt (the longest "
            "step), or check the structures and the cross-sections at that point (a structure on a nearly dry "
            "bed, a profile narrower than its "
            "neighbours)")
    return when, where, f"level {float(z[index]):.6g} m AD"

def _courant_near(sim: Simulator, point: int, u: np.ndarray) -> str:
    """``" (Courant number u·dt/dx up to C at the links there)"`` at the smallest sub-step, for messages.

    Empty without flow.
    """
    a = sim.compiled.arrays
    links = np.flatnonzero((a.lk_k1 == point) | (a.lk_k2 == point))
    if links.size == 0:
        return ""
    courant = float(np.max(np.abs(u[links]) * sim.dt / 2**MAX_HALVINGS * a.lk_ilen[links]))
    return f" (Courant number u·dt/dx up to {courant:.3g} at the links there)" if courant > 0 else ""
