"""``rivercal twin``: the twin experiments and the initial model analysis of the reference study (chapter 4).

Every run writes, under ``--out``: per suite the tables and figures of
:func:`rivercal.report.twin.write_suite`; for ``sensitivity`` those of
:func:`rivercal.report.twin.write_initial_analysis`; ``summary.json`` (what ``--json`` prints); and
``index.html`` (:func:`rivercal.report.thesis.write_report`), our numbers beside the thesis'.
"""

import json
import shlex
import sys
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rivercal.cli.common import CaseArg, JsonOpt, QuietOpt, emit_json, err_console, null_context, out_console

SCENARIO_SUITES = ("F1W0", "F0W1", "FaWc", "FaWcP", "FaWcN")
SENSITIVITY = "sensitivity"
THESIS = "thesis"
SUITE_HELP = ("F1W0, F0W1, FaWc, FaWcP, FaWcN (thesis §4-4), 'sensitivity' (the initial model analysis of thesis "
              "§4-5-1: the one-at-a-time sensitivity of Table 4-4 AND the identifiability analysis, Figs. 4-5 … 4-7; "
              "identifiability has no suite of its own, it needs only p + 1 more runs), or 'thesis' (all of them); "
              "several joined by commas. index.html is written for every run.")
PARAMS_DEFAULT = "W1,W2,W3,W4,W5,W6,W7,W8,W9,FA"


def twin(
    case: CaseArg,
    suite: Annotated[str, typer.Option(help=SUITE_HELP)],
    scenarios: Annotated[str | None, typer.Option(
        help="Only these scenarios, e.g. H1,L2 (each suite keeps the ones it has; every suite must keep one).")] = None,
    window: Annotated[str | None, typer.Option(
        help="Replace every window (suites and sensitivity): a case window or START/END (UTC).")] = None,
    params: Annotated[str, typer.Option(
        "--params", help="Parameters of the sensitivity and identifiability analysis (thesis Table 4-4).")
    ] = PARAMS_DEFAULT,
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/twin"),
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Twin experiments of the thesis: truths, perturbed starts, DuD, indicators; sensitivity; one HTML report."""
    from rivercal.model import load_model

    t0 = time.perf_counter()
    names = _suites(suite)
    scenario_names = [n for n in names if n in SCENARIO_SUITES]
    _check_window(window)
    chosen = _scenarios(scenario_names, scenarios, window)
    wanted = [p.strip() for p in params.split(",") if p.strip()]
    if SENSITIVITY in names and not wanted:
        raise ValueError("--params: give at least one parameter for the sensitivity analysis")
    if workers is not None and workers < 1:
        raise ValueError(f"--workers {workers}: must be at least 1")
    show = not (quiet or as_json)
    from rivercal.evaluate import default_workers

    workers = workers or default_workers()
    sim = load_model(case)
    _check_case(sim, names, wanted if SENSITIVITY in names else [], window)

    summary: dict = {"case": sim.case.name, "suites": {}, "workers": workers}
    results_by_suite, files_by_suite, analysis, analysis_files = {}, {}, None, {}
    if SENSITIVITY in names:
        analysis, analysis_files = _run_analysis(sim, wanted, window, workers, out, show)
        summary[SENSITIVITY] = _analysis_summary(analysis, analysis_files)
    if chosen:
        results = _run_suites(sim, chosen, workers, show)
        for name in scenario_names:
            results_by_suite[name] = [r for r in results if r.suite == name]
    from rivercal.report.twin import suite_summary, write_suite

    for name, results in results_by_suite.items():
        files_by_suite[name] = write_suite(name, results, out)
        summary["suites"][name] = {**suite_summary(results), "files": files_by_suite[name]}
        if show:
            _print_suite(name, results, summary["suites"][name])
    summary["wall_s"] = round(time.perf_counter() - t0, 1)
    complete = (set(SCENARIO_SUITES) | {SENSITIVITY}) <= set(names) and scenarios is None and window is None \
        and params == PARAMS_DEFAULT
    from rivercal.report.thesis import targets, write_report

    report = write_report(out, case=sim.case.name, command=_command(), suites=results_by_suite,
                          files=files_by_suite, analysis=analysis, analysis_files=analysis_files,
                          wall_s=summary["wall_s"], workers=workers, complete=complete)
    summary["targets"] = [{"target": t, "measured": row["measured"], "met": row["met"]}
                          for t, row in targets(results_by_suite, wall_s=summary["wall_s"], complete=complete,
                                                workers=workers).iterrows()]
    summary["report"] = str(report)
    summary = _clean(summary)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    if as_json:
        emit_json(summary)
    elif not quiet:
        out_console.print(f"{', '.join(names)} in {summary['wall_s']:.0f} s; report {report}")


def _clean(value):
    """JSON-safe: numpy scalars to Python, NaN and ±inf to None, containers recursively, the rest as str."""
    import math

    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, bool | int | str):
        return value
    return str(value)


def _command() -> str:
    return "rivercal " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:] else "rivercal twin"


def _suites(text: str) -> list[str]:
    names = []
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        expanded = [*SCENARIO_SUITES, SENSITIVITY] if item == THESIS else [item]
        for n in expanded:
            if n not in (*SCENARIO_SUITES, SENSITIVITY):
                raise ValueError(f"--suite {item!r}: choose from {', '.join((*SCENARIO_SUITES, SENSITIVITY, THESIS))} "
                                 "(several joined by commas)")
            if n not in names:
                names.append(n)
    if not names:
        raise ValueError(f"--suite {text!r}: give at least one of {', '.join((*SCENARIO_SUITES, SENSITIVITY, THESIS))}")
    return names


def _check_window(window: str | None) -> None:
    if window is None or "/" not in window:
        return
    import pandas as pd

    a, _, b = window.partition("/")
    try:
        ok = pd.Timestamp(b) > pd.Timestamp(a)
    except ValueError:
        ok = False
    if not ok:
        raise ValueError(f"--window {window!r}: expected START/END with END after START")


def _scenarios(suites: list[str], scenarios: str | None, window: str | None) -> list:
    """The scenarios to run; unknown ids fail here, before any model run."""
    from rivercal.twin.suites import suite_scenarios

    ids = [s.strip() for s in scenarios.split(",") if s.strip()] if scenarios else None
    chosen = []
    for name in suites:
        available = [s.id for s in suite_scenarios(name)]
        keep = [i for i in ids if i in available] if ids is not None else None
        if keep == []:
            raise ValueError(f"--scenarios {scenarios!r}: suite {name} has none of them (it has "
                             f"{', '.join(available)})")
        chosen += suite_scenarios(name, ids=keep, window=window)
    if ids is not None:
        every = {s.id for n in suites for s in suite_scenarios(n)}
        unknown = [i for i in ids if i not in every]
        if unknown:
            raise ValueError(f"--scenarios: no chosen suite has a scenario {unknown[0]!r}")
    return chosen


def _check_case(sim, names: list[str], params: list[str], window: str | None) -> None:
    from rivercal.twin.suites import SUITES

    known = [w.name for w in sim.case.spec.windows]
    if window is not None and "/" not in window and window not in known:
        raise ValueError(f"--window {window!r}: the case has windows {', '.join(known)}")
    defined = {p.name for p in sim.case.spec.parameters}
    missing = sorted({p for n in names if n in SUITES for p in SUITES[n].truths} - defined)
    if missing:
        raise ValueError(f"case {sim.case.name!r} does not define the parameters {missing} the suites need")
    unknown = [p for p in params if p not in defined]
    if unknown:
        raise ValueError(f"--params: unknown parameter {unknown[0]!r}; the case defines {', '.join(sorted(defined))}")
    if window is None and "moderate" not in known and SENSITIVITY in names:
        raise ValueError(f"case {sim.case.name!r} has no 'moderate' window for the sensitivity; give --window")


def _run_analysis(sim, params: list[str], window: str | None, workers: int | None, out: Path, show: bool):
    from rivercal.report.twin import write_initial_analysis
    from rivercal.twin.suites import initial_analysis

    status = err_console.status(f"initial analysis: sensitivity and identifiability of {', '.join(params)}",
                                spinner="dots") if show else null_context()
    with status:
        analysis = initial_analysis(sim, params, window or "moderate", workers=workers)
    files = write_initial_analysis(analysis, out, sim.case.name)
    if show:
        rank = analysis.sensitivity.ranking()
        out_console.print(f"initial analysis: {analysis.model_runs} runs in {analysis.wall_s:.0f} s; strongest "
                          f"{', '.join(rank.index[:4])}")
        if analysis.identifiability is not None:
            v = analysis.identifiability.verdict["verdict"]
            out_console.print("identifiability: " + ", ".join(f"{n} {v[n]}" for n in v.index), highlight=False)
    return analysis, files


def _analysis_summary(analysis, files: dict) -> dict:
    out = {"parameters": list(analysis.parameters), "window": [t.isoformat() for t in analysis.window],
           "model_runs": analysis.model_runs, "wall_s": round(analysis.wall_s, 1),
           "sensitivity": analysis.sensitivity.summary(), "files": files}
    if analysis.identifiability is not None:
        out["identifiability"] = analysis.identifiability.summary()
    return out


def _run_suites(sim, chosen: list, workers: int | None, show: bool) -> list:
    from rivercal.twin.suites import run_scenarios

    total = len(chosen)
    done: list = []
    status = err_console.status(f"0/{total} scenarios", spinner="dots") if show else null_context()
    with status as live:
        def progress(result):
            done.append(result)
            if live is not None and hasattr(live, "update"):
                live.update(f"{len(done)}/{total} scenarios ({result.suite} {result.id}: {result.iterations} "
                            "iterations)")

        return run_scenarios(sim, chosen, workers=workers, progress=progress)


def _print_suite(name: str, results, s: dict) -> None:
    table = Table(title=f"{name}: robustness {s['robustness']:.0%}, {s['model_runs_total']} model runs, "
                        f"{s['wall_s_total']:.0f} s of calibration")
    params = list(results[0].truth)
    for col in ("scenario", *[f"{p} true/start/estimate" for p in params], "iterations", "runs", "cost", "ok"):
        table.add_column(col, justify="right")
    for r in results:
        table.add_row(r.id, *[f"{r.truth[p]:g} / {r.start[p]:g} / {r.estimates[p]:.5g}" for p in params],
                      str(r.iterations), str(r.model_runs), f"{r.cost:.1e}", "yes" if r.within_tolerance else "NO")
    out_console.print(table)
