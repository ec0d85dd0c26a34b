"""``rivercal twin``: the twin experiments and the initial model analysis of the reference study (chapter 4).

The work and the files are :func:`rivercal.workflows.twin.run_thesis`'s; this module checks the options
and prints.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rivercal.cli.common import CaseArg, DaskOpt, JsonOpt, QuietOpt, Reporter, emit_json, out_console
from rivercal.cli.options import (
    check_overlap,
    check_workers,
    dask_address,
    open_model,
    output_dir,
    parse_names,
    parse_time,
    parse_window,
    workers_for,
)
from rivercal.errors import OptionError

__all__ = ["twin"]

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
    dask: DaskOpt = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Twin experiments of the thesis: truths, perturbed starts, DuD, indicators; sensitivity; one HTML report."""
    from rivercal.evaluate import default_workers
    from rivercal.workflows.twin import SCENARIO_SUITES, SENSITIVITY, run_thesis  # numerics: not loaded for --help

    names = _suites(suite)
    scenario_names = [n for n in names if n in SCENARIO_SUITES]
    _check_window(window)
    chosen = _scenarios(scenario_names, scenarios, window)
    wanted = parse_names(params, "--params")
    if SENSITIVITY in names and not wanted:
        raise OptionError("--params: give at least one parameter for the sensitivity analysis", option="--params")
    check_workers(workers)
    address = dask_address(dask, workers)
    output_dir(out)
    model = open_model(case, show_compilation=not quiet)
    _check_case(model, names, wanted if SENSITIVITY in names else [], window)
    complete = (set(SCENARIO_SUITES) | {SENSITIVITY}) <= set(names) and scenarios is None and window is None \
        and params == PARAMS_DEFAULT
    show = not (quiet or as_json)
    reporter = Reporter(show)
    with reporter.running("starting"), workers_for(workers or default_workers(), address) as where:
        done = run_thesis(model, names, chosen, wanted, out, window=window, workers=where,
                          command=_command(), complete=complete, progress=reporter)
    if as_json:
        emit_json(done.summary)
        return
    if show:
        _print_analysis(done.analysis)
        for name, results in done.suites.items():
            _print_suite(name, results, done.summary["suites"][name])
    if not quiet:
        out_console.print(f"{', '.join(names)} in {done.summary['wall_s']:.0f} s; report {done.summary['report']}")


def _command() -> str:
    return "rivercal " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:] else "rivercal twin"


def _suites(text: str) -> list[str]:
    from rivercal.workflows.twin import SCENARIO_SUITES, SENSITIVITY  # numerics: not loaded for --help

    every = (*SCENARIO_SUITES, SENSITIVITY, THESIS)
    names = []
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        expanded = [*SCENARIO_SUITES, SENSITIVITY] if item == THESIS else [item]
        for n in expanded:
            if n not in (*SCENARIO_SUITES, SENSITIVITY):
                raise OptionError(f"--suite {item!r}: choose from {', '.join(every)} (several joined by commas)",
                                  option="--suite")
            if n not in names:
                names.append(n)
    if not names:
        raise OptionError(f"--suite {text!r}: give at least one of {', '.join(every)}", option="--suite")
    return names


def _check_window(window: str | None) -> None:
    if window is None or "/" not in window:
        return
    a, _, b = window.partition("/")
    if not parse_time(b, "--window") > parse_time(a, "--window"):
        raise OptionError(f"--window {window!r}: expected START/END with END after START", option="--window")


def _scenarios(suites: list[str], scenarios: str | None, window: str | None) -> list:
    """The scenarios to run; unknown ids fail here, before any model run."""
    from rivercal.twin.suites import suite_scenarios

    ids = parse_names(scenarios, "--scenarios") if scenarios is not None else None
    if ids == []:
        raise OptionError("--scenarios: give at least one scenario id, e.g. H1,L2", option="--scenarios")
    chosen = []
    for name in suites:
        available = [s.id for s in suite_scenarios(name)]
        keep = [i for i in ids if i in available] if ids is not None else None
        if keep == []:
            raise OptionError(f"--scenarios {scenarios!r}: suite {name} has none of them (it has "
                              f"{', '.join(available)})", option="--scenarios")
        chosen += suite_scenarios(name, ids=keep, window=window)
    if ids is not None:
        every = {s.id for n in suites for s in suite_scenarios(n)}
        unknown = [i for i in ids if i not in every]
        if unknown:
            raise OptionError(f"--scenarios: no chosen suite has a scenario {unknown[0]!r}", option="--scenarios")
    return chosen


def _check_case(model, names: list[str], params: list[str], window: str | None) -> None:
    import pandas as pd

    from rivercal.twin.suites import SUITES
    from rivercal.workflows.twin import SENSITIVITY  # numerics: not loaded for --help

    known = list(model.calibration.windows)
    if window is not None and "/" not in window and window not in known:
        raise OptionError(f"--window {window!r}: the case has windows {', '.join(known)}", option="--window")
    if window is not None:  # the suites' and the analysis' runs start 24 h before their window (twin_truth)
        parse_window(model, window, warmup=pd.Timedelta(hours=24), warmup_option=None)
    defined = set(model.calibration.names)
    missing = sorted({p for n in names if n in SUITES for p in SUITES[n].truths} - defined)
    if missing:
        raise OptionError(f"case {model.name!r} does not define the parameters {missing} the suites need")
    unknown = [p for p in params if p not in defined]
    if unknown:
        raise OptionError(f"--params: unknown parameter {unknown[0]!r}; the case defines {', '.join(sorted(defined))}",
                          option="--params")
    check_overlap(model, params)
    if window is None and "moderate" not in known and SENSITIVITY in names:
        raise OptionError(f"--window: case {model.name!r} has no 'moderate' window for the sensitivity; give one",
                          option="--window")


def _print_analysis(analysis) -> None:
    if analysis is None:
        return
    rank = analysis.sensitivity.ranking()
    out_console.print(f"initial analysis: {analysis.model_runs} runs in {analysis.wall_s:.0f} s; strongest "
                      f"{', '.join(rank.index[:4])}")
    if analysis.identifiability is not None:
        v = analysis.identifiability.verdict["verdict"]
        out_console.print("identifiability: " + ", ".join(f"{n} {v[n]}" for n in v.index), highlight=False)


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
