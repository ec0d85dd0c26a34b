"""``rivercal twin``: the twin-experiment suites of the reference study (thesis chapter 4)."""

import json
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rivercal.cli.common import CaseArg, JsonOpt, QuietOpt, emit_json, err_console, null_context, out_console

SUITE_HELP = "F1W0, F0W1, FaWc, FaWcP, FaWcN, or several joined by commas."


def twin(
    case: CaseArg,
    suite: Annotated[str, typer.Option(help=SUITE_HELP)],
    scenarios: Annotated[str | None, typer.Option(help="Only these scenarios, e.g. H1,M2,L1.")] = None,
    window: Annotated[str | None, typer.Option(help="Replace the suites' window: a case window or START/END.")] = None,
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/twin"),
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Run twin-experiment suites: truth, simulated observations, perturbed starts, DuD, indicators."""
    from rivercal.model import load_model
    from rivercal.report.twin import suite_summary, write_suite
    from rivercal.twin.suites import SUITES, run_scenarios, suite_scenarios

    names = [s.strip() for s in suite.split(",") if s.strip()]
    unknown = [n for n in names if n not in SUITES]
    if unknown or not names:
        raise ValueError(f"--suite {suite!r}: choose from {', '.join(SUITES)} (several joined by commas)")
    if window is not None and "/" in window:
        import pandas as pd

        a, _, b = window.partition("/")
        try:
            if not pd.Timestamp(b) > pd.Timestamp(a):
                raise ValueError
        except ValueError:
            raise ValueError(f"--window {window!r}: expected START/END with END after START") from None
    ids = [s.strip() for s in scenarios.split(",")] if scenarios else None
    for n in names:  # unknown scenario ids fail here, before any model run
        suite_scenarios(n, ids=ids)
    sim = load_model(case)
    known = [w.name for w in sim.case.spec.windows]
    if window is not None and "/" not in window and window not in known:
        raise ValueError(f"--window {window!r}: the case has windows {', '.join(known)}")
    defined = {p.name for p in sim.case.spec.parameters}
    missing = {p for n in names for p in SUITES[n].truths} - defined
    if missing:
        raise ValueError(f"case {sim.case.name!r} does not define the parameters {sorted(missing)} the suites need")
    summary: dict = {"case": sim.case.name, "suites": {}}
    t0 = time.perf_counter()
    for name in names:
        chosen = suite_scenarios(name, ids=ids, window=window)
        total = len(chosen)
        done = []
        status = err_console.status(f"{name}: 0/{total} scenarios", spinner="dots") \
            if not (quiet or as_json) else null_context()
        with status as live:
            def progress(result, live=live, done=done, name=name, total=total):
                done.append(result)
                if live is not None and hasattr(live, "update"):
                    live.update(f"{name}: {len(done)}/{total} scenarios ({result.id}: {result.iterations} iterations)")

            t1 = time.perf_counter()
            results = run_scenarios(sim, chosen, workers=workers, progress=progress)
        files = write_suite(name, results, out)
        summary["suites"][name] = {**suite_summary(results), "wall_s": round(time.perf_counter() - t1, 1),
                                   "files": files}
        if not (quiet or as_json):
            _print_suite(name, results, summary["suites"][name])
    summary["wall_s"] = round(time.perf_counter() - t0, 1)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float) + "\n", encoding="utf-8")
    if as_json:
        emit_json(summary)
    elif not quiet:
        out_console.print(f"{len(names)} suite(s) in {summary['wall_s']:.0f} s; tables and figures in {out}")


def _print_suite(name: str, results, s: dict) -> None:
    table = Table(title=f"{name}: robustness {s['robustness']:.0%}, {s['model_runs_total']} model runs, "
                        f"{s['wall_s']:.0f} s")
    params = list(results[0].truth)
    for col in ("scenario", *[f"{p} true/start/estimate" for p in params], "iterations", "runs", "cost", "ok"):
        table.add_column(col, justify="right")
    for r in results:
        table.add_row(r.id, *[f"{r.truth[p]:g} / {r.start[p]:g} / {r.estimates[p]:.5g}" for p in params],
                      str(r.iterations), str(r.model_runs), f"{r.cost:.1e}", "yes" if r.within_tolerance else "NO")
    out_console.print(table)
