"""The batched time loop: N members advanced in one compiled call, in parallel over members.

Each member is the single-run time loop (:func:`.timeloop.run`, or :func:`.timeloop.run_ext` for a
network with D-HYDRO structures or scheduled settings) on its own state, parameters, forcing and
scratch arrays, so a member's result is bit-identical to its single run. The members are spread over
numba's threads with ``prange``; the caller sets the number of threads (``numba.set_num_threads``).

What one member writes is its own: its state rows, its output rows, its :class:`~.timeloop.Work` and —
for the extended loop, which writes scheduled settings into the network's pump capacities and the
structures' gate levels — its own copies of those arrays (the caller hands each member a ``net`` and
``sx`` whose other arrays are shared, read-only).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.lookup import hp_volume_width
from rivercal.engine.kernels.timeloop import run, run_ext

__all__ = ["run_members", "volumes"]


@njit(parallel=True, cache=True, error_model="numpy")
def run_members(nets, sxs, works, extended, crest, fric, z, dz, vol, u, q, pump_on, forcing, dt, theta, max_iter, tol,
                min_depth, vmax, out_every, obs_out, z_out, q_out, balance, status):
    """Advance every member over ``forcing.shape[1]`` steps; the arguments of :func:`.timeloop.run`, one row each.

    Parameters
    ----------
    nets, sxs, works
        Per member (typed lists): network arrays, structure arrays and scratch arrays.
    extended
        Use :func:`.timeloop.run_ext` (structures of D-HYDRO's kinds or scheduled settings).
    crest, fric
        Per member: crest levels (m AD) and friction values, shape (members, …).
    z, dz, vol, u, q, pump_on
        Per member the state (m AD, m, m³, m/s, m³/s, 0/1), updated in place, shape (members, …).
    forcing
        Shape (members or 1, steps, columns): each member's forcing, or one for all.
    dt, theta, max_iter, tol, min_depth, vmax, out_every
        As for :func:`.timeloop.run` (s, -, -, m, m, m/s, steps).
    obs_out, z_out, q_out, balance
        Per member the outputs of :func:`.timeloop.run`, shape (members, …).
    status
        Per member (status, step, index) of :func:`.timeloop.run`, shape (members, 3), int64.
    """
    n_mem = z.shape[0]
    shared = forcing.shape[0] == 1
    for k in prange(n_mem):
        m = np.int64(k)  # prange counts in uint64; the typed lists index with int64
        f = forcing[0] if shared else forcing[m]
        if extended:
            s, step, index = run_ext(nets[m], sxs[m], works[m], crest[m], fric[m], z[m], dz[m], vol[m], u[m], q[m],
                                     pump_on[m], f, dt, theta, max_iter, tol, min_depth, vmax, out_every, obs_out[m],
                                     z_out[m], q_out[m], balance[m])
        else:
            s, step, index = run(nets[m], works[m], crest[m], fric[m], z[m], dz[m], vol[m], u[m], q[m], pump_on[m], f,
                                 dt, theta, max_iter, tol, min_depth, vmax, out_every, obs_out[m], z_out[m], q_out[m],
                                 balance[m])
        status[m, 0] = s
        status[m, 1] = step
        status[m, 2] = index


@kernel
def volumes(net, z, vol):
    """The volume (m³) at every h-point for levels ``z`` (m AD), into ``vol`` (e.g. after a state analysis)."""
    for i in range(z.size):
        vol[i] = hp_volume_width(net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin,
                                 net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top,
                                 net.tab_at, net.tab_wt, i, z[i])[0]
