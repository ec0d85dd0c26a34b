"""The Picard iterations of a time step: linearise the structures, assemble and solve the levels, repeat.

Weirs and culverts are written in the same linear form as the channel links, ``u = r - f (z2 - z1)``,
with their flow area and regime taken from the current iterate of the levels
(:func:`.structures.structure_coefficients`), and so are channel links in a free overfall at a step in the bed
(:func:`.overfall.overfall_coefficients`) and the links that reach a free outfall
(:func:`.outfall.outfall_coefficients`); the level system (:func:`.assemble.assemble`) is then
solved by :func:`.solver.ldl_solve_packed`. Non-linear storage enters through the volume curve's
linearisation at the iterate, and the channel links' flow area and friction through their geometry at the
iterate (:func:`.momentum.channel_coefficients`, evaluated first at the extrapolated level,
:func:`first_iterate`, and again after every iteration that has not converged). The iterations stop when no
level changes by ``tol`` or more.
"""

from __future__ import annotations

import math

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.assemble import assemble
from rivercal.engine.kernels.codes import GEOMETRY_CONTRACT, GEOMETRY_FROM, STAT_SOLVES
from rivercal.engine.kernels.momentum import channel_coefficients
from rivercal.engine.kernels.outfall import outfall_coefficients
from rivercal.engine.kernels.overfall import overfall_coefficients
from rivercal.engine.kernels.solver import ldl_solve_packed
from rivercal.engine.kernels.structures import extended_coefficients, structure_coefficients, switch_pumps

__all__ = [
    "first_iterate",
    "follow_geometry",
    "moves",
    "picard_iterations",
    "picard_iterations_ext",
    "solve_levels",
    "solve_levels_change",
]


@kernel
def first_iterate(net, zk, z, dz, min_depth, near, ahead=1.0):
    """The first iterate of a step's levels into ``zk`` (m AD): z^n + ahead (z^n - z^{n-1}), not below the bed.

    ``ahead`` is the (sub-)step's length over the last one's where it is shorter (1 otherwise): the last change
    ``dz`` (m) extrapolated over the step to come, as the accuracy control extrapolates it
    (:func:`.fluxes.check_levels`). A step divided 2^k times after a long one would otherwise start 2^k times
    too far from its levels: past the top of a closed profile, where the volume curve bends, the iterations did
    not come back, and the smallest sub-step committed a level 3.5 km above its bed. When the extrapolation is
    good one solve suffices (the convergence test compares with it). Returns whether the iterate lies farther than
    ``near`` (m) from the levels ``z`` (m AD) at some point.
    """
    far = 0
    for i in range(z.size):
        zi = z[i]
        k = max(zi + ahead * dz[i], min(zi, net.hp_bed[i] + min_depth))
        zk[i] = k
        far += math.fabs(k - zi) > near
    return far > 0


@kernel(inline=True)
def picard_iterations(net, work, z, dz, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth, follow,
                      ahead=1.0):
    """Iterate the levels of step n+1 in ``work.zk`` (m AD): at most ``max_iter`` solves, until none moves by ``tol``.

    The first iterate is the extrapolated level (:func:`first_iterate`, from the levels ``z`` and their last change
    ``dz``, m, over ``ahead`` times the last step), and the channel links' coefficients are those of the geometry at
    time n. Each iteration linearises the structures at the current iterate and solves the level system. With
    ``follow``, where the
    first solution moves a level by more than ``GEOMETRY_FROM`` (:func:`moves`), the iterations go on in
    :func:`follow_geometry`, which also evaluates the channels' geometry at each iterate.

    Returns what :func:`follow_geometry` returns, else True (the structures' iterations stop at ``max_iter``
    without a verdict).
    """
    zk = work.zk
    # a solution within tol of an iterate that lies within GEOMETRY_FROM - tol of z moves no level by GEOMETRY_FROM
    far = first_iterate(net, zk, z, dz, min_depth, GEOMETRY_FROM - tol, ahead)
    for it in range(max_iter):
        structure_coefficients(net, work, zk, u, crest, dt)
        if net.dl_link.size:
            overfall_coefficients(net, work, zk, u, dt, it == 0)
        if net.of_link.size:
            outfall_coefficients(net, work, zk, u, dt)
        converged = solve_levels(net, work, zk, vol, u, theta, dt, tol)
        work.stats[STAT_SOLVES] += 1
        if it == 0 and follow and (far or not converged) and moves(z, zk):
            return follow_geometry(net, None, work, z, vol, u, q, pump_on, crest, theta, dt, max_iter - 1, tol,
                                   min_depth)
        if converged:
            break
    return True


@kernel
def picard_iterations_ext(net, sx, work, z, dz, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth,
                          follow, ahead=1.0):
    """:func:`picard_iterations` for a network with structures of D-HYDRO's kinds (``sx.links``).

    A separate kernel, so that a network without them passes no more arrays per step than before (each
    array passed costs a network of 400 points about 1 % of its run time, measured).
    """
    zk = work.zk
    # a solution within tol of an iterate that lies within GEOMETRY_FROM - tol of z moves no level by GEOMETRY_FROM
    far = first_iterate(net, zk, z, dz, min_depth, GEOMETRY_FROM - tol, ahead)
    for it in range(max_iter):
        structure_coefficients(net, work, zk, u, crest, dt)
        extended_coefficients(net, sx, work, zk, u, dt)
        if net.dl_link.size:
            overfall_coefficients(net, work, zk, u, dt, it == 0)
        if net.of_link.size:
            outfall_coefficients(net, work, zk, u, dt)
        converged = solve_levels(net, work, zk, vol, u, theta, dt, tol)
        work.stats[STAT_SOLVES] += 1
        if it == 0 and follow and (far or not converged) and moves(z, zk):
            return follow_geometry(net, sx, work, z, vol, u, q, pump_on, crest, theta, dt, max_iter - 1, tol,
                                   min_depth)
        if converged:
            break
    return True


@kernel
def follow_geometry(net, sx, work, z, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth):
    """Go on iterating a step whose first solution moved a level by more than ``GEOMETRY_FROM``, with the geometry.

    Each of at most ``max_iter`` iterations evaluates the channels' geometry at the current iterate
    ``work.zk`` (:func:`.momentum.channel_coefficients`, from the state at time n: levels ``z`` m AD, velocities
    ``u`` m/s, fluxes ``q`` m³/s; the pumps' fixed fluxes, which that overwrites, are set again from
    ``pump_on``), linearises the structures (``sx``: those of D-HYDRO's kinds, or None) and solves, until no level
    moves by ``tol``. Kept apart from the iterations of every step, whose compiled loop it would otherwise weigh
    down.

    Returns False when the iterations stop contracting (a change of the levels above ``GEOMETRY_FROM`` and not
    below ``GEOMETRY_CONTRACT`` times the one before: the geometry swings between two states, as on a shallow fast
    reach whose step is far longer than the water takes to cross a link; the caller then solves the step with the
    geometry of time n), else True.
    """
    zk = work.zk
    last = math.inf
    for _ in range(max_iter):
        channel_coefficients(net, work, z, zk, theta, u, q, dt, min_depth)
        switch_pumps(net, work, z, pump_on)
        structure_coefficients(net, work, zk, u, crest, dt)
        if sx is not None:
            if sx.links.size > 0:
                extended_coefficients(net, sx, work, zk, u, dt)
        if net.dl_link.size:
            overfall_coefficients(net, work, zk, u, dt, True)
        if net.of_link.size:
            outfall_coefficients(net, work, zk, u, dt)
        converged, change = solve_levels_change(net, work, zk, vol, u, theta, dt, tol)
        work.stats[STAT_SOLVES] += 1
        if change > GEOMETRY_CONTRACT * last and change > GEOMETRY_FROM:
            return False
        last = change
        if converged:
            break
    return True


@kernel
def moves(z, zk):
    """Whether some level ``zk`` (m AD) differs from ``z`` (m AD) by more than ``GEOMETRY_FROM`` (a vectorised pass)."""
    far = 0
    for i in range(z.size):
        far += math.fabs(zk[i] - z[i]) > GEOMETRY_FROM
    return far > 0


@kernel(inline=True)
def solve_levels(net, work, zk, vol, u, theta, dt, tol):
    """Assemble at ``zk``, solve, store the solution in ``zk``; returns whether no level changed by ``tol`` (m) or more.

    The test is a conjunction over the points, not a running maximum: it vectorises (a NaN counts as a change).
    """
    rhs = work.rhs
    assemble(net, work, zk, vol, u, theta, dt)
    ldl_solve_packed(net.sv_sched, net.sv_cptr, net.sv_cedge, net.sv_cother, net.sv_uptr, net.sv_ue1,
                     net.sv_ue2, net.sv_utgt, work.diag, work.off, work.lval, rhs)
    converged = True
    for i in range(zk.size):
        converged &= math.fabs(rhs[i] - zk[i]) < tol
        zk[i] = rhs[i]
    return converged


@kernel
def solve_levels_change(net, work, zk, vol, u, theta, dt, tol):
    """:func:`solve_levels`, which also returns the largest change of a level (m; infinite for a NaN)."""
    rhs = work.rhs
    assemble(net, work, zk, vol, u, theta, dt)
    ldl_solve_packed(net.sv_sched, net.sv_cptr, net.sv_cedge, net.sv_cother, net.sv_uptr, net.sv_ue1,
                     net.sv_ue2, net.sv_utgt, work.diag, work.off, work.lval, rhs)
    change = 0.0
    for i in range(zk.size):
        d = math.fabs(rhs[i] - zk[i])
        change = max(change, d if d == d else math.inf)
    converged = change < tol
    for i in range(zk.size):
        zk[i] = rhs[i]
    return converged, change
