"""The batched time loop: N members advanced in one compiled call, in parallel over members.

Each member is the single-run time loop of :mod:`.timeloop` on its own state, parameters, forcing,
controllers and scratch arrays, so a member's result is bit-identical to its single run. The members are
spread over numba's threads with ``prange``; the caller sets the number of threads
(``numba.set_num_threads``).

A member's *kit* is the tuple of its per-run records ``(net, sx, cx, work)``: network arrays, structure
arrays, controller arrays (:class:`~rivercal.engine.controllers.ControlArrays`, or ``None`` for a network
without controllers) and :class:`~.timeloop.Work`. What one member writes is its own: its state rows, its
output rows, its work arrays, its controller arrays (their state and crest series) and — for a network with
scheduled structure settings, which the loop writes into the network's pump capacities and the structures'
gate levels — its own copies of those arrays (the caller hands each member a ``net`` and ``sx`` whose other
arrays are shared, read-only).

:func:`_member` is the only place that knows the single-run loop's argument list.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.lookup import hp_volume_width
from rivercal.engine.kernels.timeloop import run, run_ext

__all__ = ["run_members", "volumes"]


@njit(parallel=True, cache=True, error_model="numpy")
def run_members(kits, extended, crest, fric, z, dz, vol, u, q, pump_on, forcing, settings, out_every, obs_out, z_out,
                q_out, balance, status):
    """Advance every member over ``forcing.shape[1]`` steps; the arguments of the single run, one row each.

    Parameters
    ----------
    kits
        Per member (typed list): its ``(net, sx, cx, work)`` (module docstring).
    extended
        Run the loop with structure and controller arrays (structures of D-HYDRO's kinds, scheduled
        settings or controllers), as the single run does; else the lean loop.
    crest, fric
        Per member: crest levels (m AD) and friction values, shape (members, …).
    z, dz, vol, u, q, pump_on
        Per member the state (m AD, m, m³, m/s, m³/s, 0/1), updated in place, shape (members, …).
    forcing
        Shape (members or 1, steps, columns): each member's forcing, or one for all.
    settings
        ``(dt, theta, max_iter, tol, min_depth, vmax)`` of the single run (s, -, -, m, m, m/s).
    out_every
        Output every ``out_every`` steps.
    obs_out, z_out, q_out, balance
        Per member the outputs of the single run, shape (members, …).
    status
        Per member (status, step, index) of the single run, shape (members, 3), int64.
    """
    n_mem = z.shape[0]
    shared = forcing.shape[0] == 1
    for k in prange(n_mem):
        m = np.int64(k)  # prange counts in uint64; the typed lists index with int64
        f = forcing[0] if shared else forcing[m]
        s, step, index = _member(kits[m], extended, crest[m], fric[m], z[m], dz[m], vol[m], u[m], q[m], pump_on[m], f,
                                 settings, out_every, obs_out[m], z_out[m], q_out[m], balance[m])
        status[m, 0] = s
        status[m, 1] = step
        status[m, 2] = index


@njit(cache=True, error_model="numpy")
def _member(kit, extended, crest, fric, z, dz, vol, u, q, pump_on, forcing, settings, out_every, obs_out, z_out, q_out,
            balance):
    """One member's single run; returns its (status, step, index)."""
    net, sx, cx, work = kit
    dt, theta, max_iter, tol, min_depth, vmax = settings
    if extended:
        return run_ext(net, sx, cx, work, crest, fric, z, dz, vol, u, q, pump_on, forcing, dt, theta, max_iter, tol,
                       min_depth, vmax, out_every, obs_out, z_out, q_out, balance)
    return run(net, work, crest, fric, z, dz, vol, u, q, pump_on, forcing, dt, theta, max_iter, tol, min_depth, vmax,
               out_every, obs_out, z_out, q_out, balance)


@kernel
def volumes(net, z, vol):
    """The volume (m³) at every h-point for levels ``z`` (m AD), into ``vol`` (e.g. after a state analysis)."""
    for i in range(z.size):
        vol[i] = hp_volume_width(net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin,
                                 net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top,
                                 net.tab_at, net.tab_wt, i, z[i])[0]
