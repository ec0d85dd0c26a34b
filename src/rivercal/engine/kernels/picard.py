"""The Picard iterations of a time step: linearise the structures, assemble and solve the levels, repeat.

Weirs and culverts are written in the same linear form as the channel links, ``u = r - f (z2 - z1)``,
with their flow area and regime taken from the current iterate of the levels
(:func:`.structures.structure_coefficients`), and so are channel links in a free overfall at a step in the bed
(:func:`.overfall.overfall_coefficients`) and the links that reach a free outfall
(:func:`.outfall.outfall_coefficients`); the level system (:func:`.assemble.assemble`) is then
solved by :func:`.solver.ldl_solve_packed`. Non-linear storage enters through the volume curve's
linearisation at the iterate. The iterations stop when no level changes by ``tol`` or more.
"""

from __future__ import annotations

import math

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.assemble import assemble
from rivercal.engine.kernels.codes import STAT_SOLVES
from rivercal.engine.kernels.outfall import outfall_coefficients
from rivercal.engine.kernels.overfall import overfall_coefficients
from rivercal.engine.kernels.solver import ldl_solve_packed
from rivercal.engine.kernels.structures import extended_coefficients, structure_coefficients

__all__ = ["picard_iterations", "picard_iterations_ext", "solve_levels"]


@kernel
def picard_iterations(net, work, z, dz, vol, u, crest, theta, dt, max_iter, tol, min_depth):
    """Iterate the levels of step n+1 into ``work.zk`` (m AD): at most ``max_iter`` solves, until none moves by ``tol``.

    The first iterate is the extrapolated level z^n + (z^n - z^{n-1}) (not below the bed): when the
    extrapolation is good one solve suffices (the convergence test compares with it). Each iteration
    linearises the structures at the current iterate and solves the level system.
    """
    zk = work.zk
    for i in range(z.size):
        zk[i] = max(z[i] + dz[i], min(z[i], net.hp_bed[i] + min_depth))
    for it in range(max_iter):
        structure_coefficients(net, work, zk, u, crest, dt)
        if net.dl_link.size:
            overfall_coefficients(net, work, zk, u, dt, it == 0)
        if net.of_link.size:
            outfall_coefficients(net, work, zk, u, dt)
        converged = solve_levels(net, work, zk, vol, u, theta, dt, tol)
        work.stats[STAT_SOLVES] += 1
        if converged:
            break


@kernel
def picard_iterations_ext(net, sx, work, z, dz, vol, u, crest, theta, dt, max_iter, tol, min_depth):
    """:func:`picard_iterations` for a network with structures of D-HYDRO's kinds (``sx.links``).

    A separate kernel, so that a network without them passes no more arrays per step than before (each
    array passed costs a network of 400 points about 1 % of its run time, measured).
    """
    zk = work.zk
    for i in range(z.size):
        zk[i] = max(z[i] + dz[i], min(z[i], net.hp_bed[i] + min_depth))
    for it in range(max_iter):
        structure_coefficients(net, work, zk, u, crest, dt)
        extended_coefficients(net, sx, work, zk, u, dt)
        if net.dl_link.size:
            overfall_coefficients(net, work, zk, u, dt, it == 0)
        if net.of_link.size:
            outfall_coefficients(net, work, zk, u, dt)
        converged = solve_levels(net, work, zk, vol, u, theta, dt, tol)
        work.stats[STAT_SOLVES] += 1
        if converged:
            break


@kernel
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
