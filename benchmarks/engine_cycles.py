"""Where a step's time goes inside the time loop itself: each phase of a step timed with the processor's cycle counter.

Usage: ``python benchmarks/engine_cycles.py [--case synthetic] [--days 7] [--repeats 7]``. Prints one JSON object:
per phase of a (sub-)step its time per step (ns) and share, from the run whose step loop took the fewest cycles of
``repeats``, and how many points per step had their volume curve looked up again (their level left the piece of
the last look-up, :func:`rivercal.engine.kernels.assemble.assemble`).

:mod:`engine_profile` times each kernel on its own, in a loop that keeps its data in the fastest caches and, for the
assembly, on levels whose volume-curve pieces are already known; the time loop runs them one after the other on a
moving state. This script runs the time loop itself, on a copy of its source (``timeloop.py``) with the cycle counter
(``llvm.readcyclecounter``) read between the phases of each (sub-)step, and with the Picard iterations of a network
without D-HYDRO's structures replaced by :func:`_picard`, which mirrors
:func:`rivercal.engine.kernels.picard.picard_iterations` with the counter read between its parts (keep the two
alike). The copy is compiled on each run (about 15 s) and never cached; the results are those of the engine (the
counter reads change no arithmetic). Cycles are converted to ns by the counter's rate over the whole step loop.
The counter itself costs some 20 ns per read, a few per step. A network with D-HYDRO's structures (the extended
time loop) is not instrumented.
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

import rivercal.engine.simulator as simulator
from rivercal.engine.kernels import timeloop
from rivercal.model import load_model

#: The counter's slots: (sub-)step phases of :func:`rivercal.engine.kernels.timeloop._step`, then the parts of
#: :func:`_picard`, then the look-ups counted.
PHASES = {1: "forcing", 2: "channel_coefficients", 3: "step_control_forecast", 4: "pumps_and_picard",
          5: "fluxes", 6: "screen", 7: "commit", 9: "record_and_loop",
          10: "picard.first_iterate", 11: "picard.structures", 12: "picard.assemble", 13: "picard.ldl_solve",
          14: "picard.convergence_test", 15: "picard.follow_geometry"}
LOOKUPS = 8
STEP = 0

_HEADER = '''
from llvmlite import ir as _ir
from numba import types as _types
from numba.core import cgutils as _cgutils
from numba.extending import intrinsic as _intrinsic
from rivercal.engine.kernels.assemble import assemble as _assemble
from rivercal.engine.kernels.codes import GEOMETRY_FROM as _GEOMETRY_FROM
from rivercal.engine.kernels.codes import STAT_SOLVES as _STAT_SOLVES
from rivercal.engine.kernels.picard import first_iterate as _first_iterate
from rivercal.engine.kernels.picard import follow_geometry as _follow_geometry
from rivercal.engine.kernels.picard import moves as _moves
from rivercal.engine.kernels.solver import ldl_solve_packed as _ldl_solve_packed
from rivercal.engine.kernels.structures import structure_coefficients as _structure_coefficients


@_intrinsic
def _cycles(typingctx):
    def codegen(context, builder, signature, args):
        fn = _cgutils.get_or_insert_function(builder.module, _ir.FunctionType(_ir.IntType(64), []),
                                             "llvm.readcyclecounter")
        return builder.call(fn, [])
    return _types.int64(), codegen
'''


def _picard(net, work, z, dz, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth, follow, clk, ahead):
    """:func:`rivercal.engine.kernels.picard.picard_iterations` with the counter read between its parts."""
    zk = work.zk
    a0 = _cycles()  # noqa: F821 -- defined in the header of the copy
    far = _first_iterate(net, zk, z, dz, min_depth, _GEOMETRY_FROM - tol, ahead)  # noqa: F821
    clk[10] += _cycles() - a0  # noqa: F821
    for it in range(max_iter):
        b0 = _cycles()  # noqa: F821
        _structure_coefficients(net, work, zk, u, crest, dt)  # noqa: F821
        clk[11] += _cycles() - b0  # noqa: F821
        for i in range(zk.size):  # the points whose volume curve the assembly looks up again (not timed)
            clk[8] += not ((work.zlo[i] <= zk[i]) & (zk[i] <= work.zhi[i]))
        b1 = _cycles()  # noqa: F821
        rhs = work.rhs
        _assemble(net, work, zk, vol, u, theta, dt)  # noqa: F821
        b2 = _cycles()  # noqa: F821
        _ldl_solve_packed(net.sv_sched, net.sv_cptr, net.sv_cedge, net.sv_cother, net.sv_uptr,  # noqa: F821
                          net.sv_ue1, net.sv_ue2, net.sv_utgt, work.diag, work.off, work.lval, rhs)
        b3 = _cycles()  # noqa: F821
        converged = True
        for i in range(zk.size):
            converged &= abs(rhs[i] - zk[i]) < tol
            zk[i] = rhs[i]
        b4 = _cycles()  # noqa: F821
        clk[12] += b2 - b1
        clk[13] += b3 - b2
        clk[14] += b4 - b3
        work.stats[_STAT_SOLVES] += 1  # noqa: F821
        if it == 0 and follow and (far or not converged) and _moves(z, zk):  # noqa: F821
            c0 = _cycles()  # noqa: F821
            followed = _follow_geometry(net, None, work, z, vol, u, q, pump_on, crest, theta, dt,  # noqa: F821
                                        max_iter - 1, tol, min_depth)
            clk[15] += _cycles() - c0  # noqa: F821
            return followed
        if converged:
            break
    return True


def _replace(text: str, old: str, new: str) -> str:
    if old not in text:
        raise SystemExit(f"engine_cycles: the time loop's source changed, cannot instrument it at:\n{old}")
    return text.replace(old, new, 1)


def _before(text: str, needle: str, insert: str) -> str:
    """``insert`` before the line of ``text`` that holds ``needle`` first."""
    at = text.find(needle)
    if at < 0:
        raise SystemExit(f"engine_cycles: the time loop's source changed, cannot instrument it at:\n{needle}")
    at = text.rfind("\n", 0, at) + 1
    return text[:at] + insert + text[at:]


def _instrumented(folder: Path):
    """The copy of the time loop with the counter reads, imported from ``folder``."""
    s = Path(inspect.getsourcefile(timeloop)).read_text()
    s = _replace(s, "\n__all__", _HEADER + "\n__all__")
    s = _replace(s, "q_out, balance):\n    \"\"\"Advance the state over ``forcing.shape[0]``",
                 "q_out, balance, clk):\n    \"\"\"Advance the state over ``forcing.shape[0]``")
    s = _replace(s, "        status, index, swap = _step(net, None, None,",
                 "        c0 = _cycles()\n        status, index, swap = _step(net, None, None,")
    s = _replace(s, "courant, balance)\n        if swap:",
                 "courant, balance, clk)\n        c1 = _cycles()\n        clk[0] += c1 - c0\n        if swap:")
    s = _replace(s, """            record(net, (n + 1) // out_every, z, q0, obs_out, z_out, q_out)
    _keep(u0, q0, u, q)
    return STATUS_OK, forcing.shape[0], -1


@entry
def run_ext""", """            record(net, (n + 1) // out_every, z, q0, obs_out, z_out, q_out)
        clk[9] += _cycles() - c1
    _keep(u0, q0, u, q)
    return STATUS_OK, forcing.shape[0], -1


@entry
def run_ext""")
    s = _replace(s, "min_depth, vmax, courant, balance):\n    \"\"\"Advance the state over step ``n``",
                 "min_depth, vmax, courant, balance, clk):\n    \"\"\"Advance the state over step ``n``")
    s = _replace(s, "        level = _level(stats)\n", "        t0 = _cycles()\n        level = _level(stats)\n")
    for slot, line in ((1, "        fastest = channel_coefficients("), (2, "        if _too_fast("),
                       (3, "        switched = switch_pumps("), (4, "        fluxes_within_volume(net"),
                       (5, " = _screen(net, work, z, dz, u1,"), (6, "        if status == STATUS_OK:\n")):
        s = _before(s, line, f"        t{slot} = _cycles()\n        clk[{slot}] += t{slot} - t{slot - 1}\n")
    s = _replace(s, """            stats[STAT_REDONE] += 1
            status = STATUS_OK
""", """            stats[STAT_REDONE] += 1
            status = STATUS_OK
        clk[7] += _cycles() - t6
""")
    s = _replace(s, """        if sx is None:
            followed = picard_iterations(net, work, z, dz, vol, u0, q0, pump_on, crest, theta, h, max_iter, tol,
                                         min_depth, True, ahead)""", """        if sx is None:
            followed = _picard(net, work, z, dz, vol, u0, q0, pump_on, crest, theta, h, max_iter, tol, min_depth,
                               True, clk, ahead)""")
    s += "\n\n@kernel(inline=True)\n" + re.sub(r"  # noqa: F821.*", "", inspect.getsource(_picard))
    return _load_plain(s, folder, "timeloop_cycles")


def _load_plain(text: str, folder: Path, name: str):
    """Import the patched time loop ``text`` as module ``name``, compiled without rivercal's on-disk cache."""
    text = text.replace("@entry\n", "@_plain\n").replace("@kernel\n", "@_plain\n").replace(
        "@kernel(inline=True)\n", "@_plain_inline\n")
    text = _replace(text, "from rivercal.engine.kernels._jit import entry, kernel\n",
                    "from numba import njit as _njit\n"
                    "_plain = _njit(error_model='numpy', _nrt=False, nogil=True)\n"
                    "_plain_inline = _njit(error_model='numpy', _nrt=False, nogil=True, forceinline=True)\n")
    path = folder / f"{name}.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", default="synthetic")
    parser.add_argument("--days", type=float, default=7.0)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    sim = load_model(args.case)
    if sim.extended:
        raise SystemExit("engine_cycles: the case needs the extended time loop, which is not instrumented")
    clk = np.zeros(16, dtype=np.int64)
    with tempfile.TemporaryDirectory(prefix="rivercal-cycles-") as folder:
        module = _instrumented(Path(folder))
        simulator.run = lambda *a: module.run(*a, clk)  # the copy in place of the time loop, in this process
        start = sim.start
        end = start + pd.Timedelta(days=args.days)
        state = sim.initial_state(start)
        sim.simulate(start=start, end=end, state=state)  # compiles the copy
        best = None
        for _ in range(args.repeats):
            clk[:] = 0
            result, _ = sim.simulate(start=start, end=end, state=state)
            if best is None or clk[STEP] < best[1][STEP]:
                best = (result.wall_time, clk.copy())
    wall, c = best
    steps = sim.last_run_stats["steps"]
    ns_per_cycle = wall * 1e9 / (c[STEP] + c[9])
    phases = {name: {"ns_per_step": round(c[k] * ns_per_cycle / steps, 1), "share": round(c[k] / c[STEP], 3)}
              for k, name in PHASES.items()}
    print(json.dumps({
        "case": sim.case.name, "points": sim.compiled.n_hpoints, "steps": steps,
        "solves_per_step": round(sim.last_run_stats["solves"] / steps, 3),
        "wall_ms": round(wall * 1e3, 2), "step_ns": round(c[STEP] * ns_per_cycle / steps, 1),
        "counter_ghz": round(1.0 / ns_per_cycle, 3), "volume_lookups_per_step": round(c[LOOKUPS] / steps, 2),
        "phases": phases,
    }, indent=1))


if __name__ == "__main__":
    main()
