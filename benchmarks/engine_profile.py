"""Where the engine's time goes: each kernel of one time step, timed in a compiled loop.

Usage: ``python benchmarks/engine_profile.py [--case synthetic] [--days 7] [--repeats 5]``. Prints one
JSON object: per kernel the time of one call (ns, the minimum over ``repeats`` loops of ``calls`` calls),
how often the time loop calls it per step (from the run's own counters), and the resulting time per
simulated period (ms); next to it the measured wall time of the whole run (median of ``repeats``), so the
unexplained rest (loop control, record, cache effects between kernels) is visible.

The kernels run on the state at the end of the simulated period (flowing, weirs active), so every
branch they take is a branch the real run takes. Kernels that change the state (apply_forcing,
finish_step) are not timed; their share is in the rest.
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
from rivercal.engine.kernels.fluxes import compute_fluxes, limit_draining_links
from rivercal.engine.kernels.momentum import _link_geometry, _momentum_other, _momentum_simple
from rivercal.engine.kernels.solver import ldl_solve_packed
from rivercal.engine.kernels.structures import extended_coefficients, structure_coefficients, switch_pumps
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
    walls = []
    for _ in range(args.repeats):
        result, state = sim.simulate(start=start, end=end, state=state0)
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
    wall = statistics.median(walls)
    accounted = sum(k["ms_per_run"] for k in kernels.values())
    print(json.dumps({
        "case": sim.case.name, "points": sim.compiled.n_hpoints, "links": sim.compiled.n_links,
        "mo_runs_links": int(net.mo_runs[:, 1].sum()) if net.mo_runs.size else 0, "mo_other_links": net.mo_other.size,
        "steps": steps, "solves_per_step": round(solves / steps, 3), "drying_resolves": resolves,
        "wall_ms_median": round(wall * 1e3, 2), "kernels": kernels, "accounted_ms": round(accounted, 2),
        "rest_ms": round(wall * 1e3 - accounted, 2),
    }, indent=1))


if __name__ == "__main__":
    main()
