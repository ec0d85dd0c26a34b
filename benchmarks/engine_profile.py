"""Where the engine's time goes: each kernel of one time step, timed in a compiled loop.

Usage: ``python benchmarks/engine_profile.py [--case synthetic] [--days 7] [--repeats 5]``. Prints one
JSON object: per kernel the time of one call (ns, the minimum over ``repeats`` loops of ``calls`` calls),
how often the time loop calls it per step (from the run's own counters), and the resulting time per
simulated period (ms); next to it the measured wall and processor time of the whole run (medians of ``repeats``;
``unaccounted_ms`` is the processor time less all the parts), so what the parts timed alone do not explain is
visible: mostly the same kernels running slower in the time loop than alone (``benchmarks/engine_cycles.py``
times them there).

The kernels run on the state at the end of the simulated period (flowing, weirs active), so every
branch they take is a branch the real run takes. The rest of a step is timed too, part by part (``rest`` in the
output): the forcing, the first iterate, the step control's forecast, the convergence test of each solve, the
screen, the commit and the record. The screen and the commit take the state one step before the end and the
levels solved in the last step, so that their checks see a real step's change; the commit changes the state, so
it is timed on copies that each call restores first, less the time of that restore.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numba
import numpy as np
import pandas as pd

from rivercal.engine.kernels.assemble import assemble
from rivercal.engine.kernels.codes import GEOMETRY_FROM, LINK_CHANNEL, MAX_HALVINGS
from rivercal.engine.kernels.fluxes import compute_fluxes, finish_step, limit_draining_links
from rivercal.engine.kernels.forcing import apply_forcing
from rivercal.engine.kernels.momentum import _link_geometry, _momentum_other, _momentum_simple
from rivercal.engine.kernels.picard import first_iterate
from rivercal.engine.kernels.record import record
from rivercal.engine.kernels.solver import ldl_solve_packed
from rivercal.engine.kernels.stability import explicit_amplification
from rivercal.engine.kernels.structures import extended_coefficients, structure_coefficients, switch_pumps
from rivercal.engine.kernels.timeloop import _accuracy_level, _level, _relax, _screen, _too_fast
from rivercal.model import load_model


@numba.njit
def _geometry(net, work, z, theta, u, md, calls):
    for _ in range(calls):
        _link_geometry(net, work, z, z, theta, u, md, False)  # the geometry of time n, as each step's first call


@numba.njit
def _simple(net, work, z, u, q, dt, calls):
    for _ in range(calls):
        _momentum_simple(net, work, z, u, q, dt)


@numba.njit
def _other(net, work, z, theta, u, q, dt, calls):
    for _ in range(calls):
        for link in net.mo_other:
            _momentum_other(net, work, link, z, z, theta, u, q, dt)


@numba.njit
def _structures(net, sx, work, z, u, crest, pump_on, dt, calls):
    for _ in range(calls):
        switch_pumps(net, work, z, pump_on)
        structure_coefficients(net, work, z, u, crest, dt)
        extended_coefficients(net, sx, work, z, u, dt)


@numba.njit
def _assemble(net, work, z, vol, u, theta, dt, calls):
    for _ in range(calls):
        assemble(net, work, z, vol, u, theta, dt)


@numba.njit
def _ldl(net, work, diag, off, rhs, calls):
    for _ in range(calls):
        work.diag[:] = diag   # the factorisation overwrites the matrix: restore it (timed separately)
        work.off[:] = off
        work.rhs[:] = rhs
        ldl_solve_packed(net.sv_sched, net.sv_cptr, net.sv_cedge, net.sv_cother, net.sv_uptr, net.sv_ue1,
                         net.sv_ue2, net.sv_utgt, work.diag, work.off, work.lval, work.rhs)


@numba.njit
def _restore(work, diag, off, rhs, calls):
    for _ in range(calls):
        work.diag[:] = diag
        work.off[:] = off
        work.rhs[:] = rhs


@numba.njit
def _fluxes(net, work, theta, u, un, qn, vol, dt, calls):
    for _ in range(calls):
        compute_fluxes(net, work, theta, u, un, qn)
        limit_draining_links(net, work, vol, dt, qn)


@numba.njit
def _forcing(net, work, forcing, edges, dt, vol, z, calls):
    for _ in range(calls):
        apply_forcing(net, work, 0, forcing, edges, dt, vol, z, 1.0, 0.0, 1.0)  # an undivided step


@numba.njit
def _first(net, work, z, dz, md, near, calls):
    for _ in range(calls):
        first_iterate(net, work.zk, z, dz, md, near)


@numba.njit
def _control(net, work, z, u, dt, theta, md, fastest, calls):
    for _ in range(calls):  # the step control of an undivided step: its levels, the forecast, the relaxation
        _accuracy_level(work.stats)
        level = _level(work.stats)
        _too_fast(net, work, z, u, dt, theta, md, fastest, level)
        _relax(work.stats, 1 << MAX_HALVINGS)


@numba.njit
def _amplification(net, work, z, u, dt, theta, md, calls):
    for _ in range(calls):
        explicit_amplification(net, work, z, u, dt, theta, md)


@numba.njit
def _converged(zk, rhs, tol, calls):
    converged = True
    for _ in range(calls):  # the test of picard.solve_levels after each solve (rhs holds the solution)
        converged = True
        for i in range(zk.size):
            converged &= abs(rhs[i] - zk[i]) < tol
            zk[i] = rhs[i]
    return converged


@numba.njit
def _screen_loop(net, work, z, dz, un, vmax, calls):
    for _ in range(calls):
        _screen(net, work, z, dz, un, vmax, 0, True, 0.0)


@numba.njit
def _commit(net, work, dt, z, dz, vol, un, qn, balance, z0, dz0, vol0, swing0, flick0, zk0, calls):
    for _ in range(calls):
        _restore_state(work, z, dz, vol, z0, dz0, vol0, swing0, flick0, zk0)
        finish_step(net, work, dt, np.inf, z, dz, vol, un, qn, balance, True)


@numba.njit
def _restore_state(work, z, dz, vol, z0, dz0, vol0, swing0, flick0, zk0):
    z[:] = z0
    dz[:] = dz0
    vol[:] = vol0
    work.swing[:] = swing0
    work.flick[:] = flick0
    work.zk[:] = zk0


@numba.njit
def _restore_only(work, z, dz, vol, z0, dz0, vol0, swing0, flick0, zk0, calls):
    for _ in range(calls):
        _restore_state(work, z, dz, vol, z0, dz0, vol0, swing0, flick0, zk0)


@numba.njit
def _record(net, z, q, obs, z_out, q_out, calls):
    for _ in range(calls):
        record(net, 1, z, q, obs, z_out, q_out)


def _time(fn, args, calls: int, repeats: int) -> float:
    """Minimum time of one call, ns."""
    fn(*args, 1)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        fn(*args, calls)
        best = min(best, (time.perf_counter_ns() - t0) / calls)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="synthetic")
    parser.add_argument("--days", type=float, default=7.0)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--calls", type=int, default=2000)
    args = parser.parse_args()

    sim = load_model(args.case)
    start = sim.start
    end = start + pd.Timedelta(days=args.days)
    state0 = sim.initial_state(start)
    sim.simulate(start=start, end=end, state=state0)
    walls, cpus = [], []
    for _ in range(args.repeats):
        cpu0 = time.process_time()
        result, state = sim.simulate(start=start, end=end, state=state0)
        cpus.append(time.process_time() - cpu0)
        walls.append(result.wall_time)
    counts = sim.last_run_stats
    net, work, s = sim.compiled.arrays, sim._work, sim.settings
    crest, fric = sim.parameter_arrays(None)
    dt, theta, md = float(s.dt), float(s.theta), float(s.min_depth)
    z, vol, u, q = state.z, state.vol, state.u, state.q
    for link in range(work.lfric.size):
        work.lfric[link] = fric[net.lk_fric[link]]
    un, qn = work.un.copy(), work.qn.copy()

    steps, solves, resolves = counts["steps"], counts["solves"], counts["drying_resolves"]
    per_step = {"geometry": 1, "momentum_inner": 1, "momentum_other": 1, "structures": solves / steps,
                "assemble": (solves + resolves) / steps, "ldl_solve": (solves + resolves) / steps,
                "fluxes_and_drying": 1 + resolves / steps}
    c, r = args.calls, args.repeats
    ns = {
        "geometry": _time(_geometry, (net, work, z, theta, u, md), c, r),
        "momentum_inner": _time(_simple, (net, work, z, u, q, dt), c, r),
        "momentum_other": _time(_other, (net, work, z, theta, u, q, dt), c, r),
        "structures": _time(_structures, (net, sim.compiled.structures, work, z, u, crest, state.pump_on.copy(), dt),
                            c, r),
        "assemble": _time(_assemble, (net, work, z.copy(), vol, u, theta, dt), c, r),
    }
    diag, off, rhs = work.diag.copy(), work.off.copy(), work.rhs.copy()
    ns["ldl_solve"] = (_time(_ldl, (net, work, diag, off, rhs), c, r)
                       - _time(_restore, (work, diag, off, rhs), c, r))
    ns["fluxes_and_drying"] = _time(_fluxes, (net, work, theta, u, un, qn, vol.copy(), dt), c, r)
    kernels = {k: {"ns_per_call": round(v, 1), "calls_per_step": round(per_step[k], 3),
                   "ms_per_run": round(v * per_step[k] * steps / 1e6, 2)} for k, v in ns.items()}
    rest, rest_per_step, amplified = _rest(sim, state0, start, end, counts, c, r)
    rest = {k: {"ns_per_call": round(v, 1), "calls_per_step": round(rest_per_step[k], 3),
                "ms_per_run": round(v * rest_per_step[k] * steps / 1e6, 2)} for k, v in rest.items()}
    wall = statistics.median(walls)
    cpu = statistics.median(cpus)  # on a shared machine steadier than the wall time
    accounted = sum(k["ms_per_run"] for k in kernels.values())
    accounted_rest = sum(k["ms_per_run"] for k in rest.values())
    print(json.dumps({
        "case": sim.case.name, "points": sim.compiled.n_hpoints, "links": sim.compiled.n_links,
        "mo_runs_links": int(net.mo_runs[:, 1].sum()) if net.mo_runs.size else 0, "mo_other_links": net.mo_other.size,
        "steps": steps, "solves_per_step": round(solves / steps, 3), "drying_resolves": resolves,
        "wall_ms_median": round(wall * 1e3, 2), "cpu_ms_median": round(cpu * 1e3, 2), "kernels": kernels,
        "accounted_ms": round(accounted, 2), "rest": rest, "amplification_runs": amplified,
        "accounted_rest_ms": round(accounted_rest, 2),
        "unaccounted_ms": round(cpu * 1e3 - accounted - accounted_rest, 2),
    }, indent=1))


def _rest(sim, state0, start, end, counts, c, r):
    """The parts of a step outside the kernels of :func:`main`: ns per call, calls per step, and whether the
    step control's forecast (:func:`.stability.explicit_amplification`) runs at the end of the period."""
    s = sim.settings
    dt, theta, md = float(s.dt), float(s.theta), float(s.min_depth)
    tol, vmax = float(s.tolerance), float(s.max_velocity)
    step = pd.Timedelta(seconds=dt)
    _, prev = sim.simulate(start=start, end=end - step, state=state0, output_interval=dt)
    _, last = sim.simulate(start=end - step, end=end, state=prev, output_interval=dt)
    net, work = sim.compiled.arrays, sim._work
    forcing, edges = sim._forcing(end - step, 1, False)
    wet = (net.lk_type == LINK_CHANNEL) & (work.area > 0.0)
    fastest = float(np.max(np.abs(last.u) * net.lk_ilen, where=wet, initial=0.0))
    amplified = fastest * dt > 1.0
    steps = counts["steps"]
    taken = (steps - counts["divided_steps"] + counts["substeps"]) / steps  # (sub-)steps per step
    solves = (counts["solves"] + counts["drying_resolves"]) / steps
    out_every = round(float(s.output_interval) / dt)
    ns = {
        "forcing": _time(_forcing, (net, work, forcing, edges, dt, prev.vol.copy(), prev.z), c, r),
        "first_iterate": _time(_first, (net, work, prev.z, prev.dz, md, GEOMETRY_FROM - tol), c, r),
        "step_control": _time(_control, (net, work, prev.z, prev.u, dt, theta, md, fastest), c, r),
        "amplification": _time(_amplification, (net, work, prev.z, prev.u, dt, theta, md), c, r),
        "convergence_test": _time(_converged, (work.zk, last.z.copy(), tol), c, r),
    }
    work.zk[:] = last.z
    ns["screen"] = _time(_screen_loop, (net, work, prev.z, prev.dz, last.u, vmax), c, r)
    _fluxes(net, work, theta, prev.u, work.un, work.qn, prev.vol.copy(), dt, 1)  # the net inflows of the last step
    saved = (prev.z.copy(), prev.dz.copy(), prev.vol.copy(), work.swing.copy(), work.flick.copy(), last.z.copy())
    state = (prev.z.copy(), prev.dz.copy(), prev.vol.copy())
    ns["commit"] = (_time(_commit, (net, work, dt, *state, work.un, work.qn, np.zeros(net.b_hp.size + 1), *saved),
                          c, r)
                    - _time(_restore_only, (work, *state, *saved), c, r))
    obs = np.zeros((2, net.ob_type.size))
    ns["record"] = _time(_record, (net, last.z, last.q, obs, np.empty((0, 0)), np.empty((0, 0))), c, r)
    per_step = {"forcing": taken, "first_iterate": taken, "step_control": 1.0,
                "amplification": taken if amplified else 0.0, "convergence_test": solves, "screen": taken,
                "commit": taken, "record": 1.0 / out_every}
    return ns, per_step, bool(amplified)


if __name__ == "__main__":
    main()
