"""The twin experiments and the initial model analysis of the reference study (thesis chapter 4), with the report.

Writes, under ``out``: per suite the tables and figures of :func:`rivercal.report.twin.write_suite`;
for the sensitivity those of :func:`rivercal.report.twin.write_initial_analysis`; ``summary.json``
(the summary); and ``index.html`` (:func:`rivercal.report.thesis.write_report`), our numbers beside
the thesis'.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rivercal.models.contract import Model
from rivercal.workflows.progress import NO_PROGRESS, Progress, jsonable

__all__ = ["SCENARIO_SUITES", "SENSITIVITY", "ThesisRun", "run_thesis"]

#: The scenario suites of thesis §4-4.
SCENARIO_SUITES = ("F1W0", "F0W1", "FaWc", "FaWcP", "FaWcN")
#: The initial model analysis of thesis §4-5-1 (sensitivity and identifiability).
SENSITIVITY = "sensitivity"


@dataclass
class ThesisRun:
    """What :func:`run_thesis` did.

    The summary (as written to ``summary.json``), the results per suite
    (:class:`~rivercal.twin.suites.ScenarioResult` lists) and the initial analysis (or None).
    """

    summary: dict[str, Any]
    suites: dict[str, list[Any]] = field(default_factory=dict)
    analysis: Any = None


def run_thesis(model: Model, suites: Sequence[str], scenarios: Sequence[Any], parameters: Sequence[str],
               out: str | Path, *, window: str | None = None, workers: Any = 1, command: str = "",
               complete: bool = False, progress: Progress = NO_PROGRESS) -> ThesisRun:
    """Run the chosen suites' ``scenarios`` and, if ``sensitivity`` is among ``suites``, the initial analysis.

    Parameters
    ----------
    model
        The default case's model (:func:`rivercal.model.load_model`).
    suites
        Names from :data:`SCENARIO_SUITES` and :data:`SENSITIVITY`.
    scenarios
        The scenarios to run (:func:`rivercal.twin.suites.suite_scenarios`), all suites together.
    parameters
        Parameters of the sensitivity and identifiability analysis.
    out
        Output folder (created).
    window
        The analysis' window (a case window or START/END); None: ``moderate``.
    workers
        Worker processes (one pool for every scenario), or a :class:`~rivercal.evaluate.DaskCluster`: then
        the initial analysis and the scenarios go to the cluster at the same time, so that it stays busy.
    command
        The command that asked for this, for the report.
    complete
        Whether this is the whole chapter with its defaults (the report then checks the targets).
    progress
        Where to say what happens: one step per scenario.
    """
    from rivercal.evaluate import DaskCluster, describe_workers
    from rivercal.report.thesis import targets, write_report
    from rivercal.report.twin import suite_summary, write_initial_analysis, write_suite
    from rivercal.twin.suites import initial_analysis, run_scenarios

    t0 = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    where = describe_workers(workers)
    done = ThesisRun(summary={"case": model.name, "suites": {}, "workers": where})
    analysis_files: dict[str, str] = {}
    side = ThreadPoolExecutor(1, thread_name_prefix="rivercal-analysis")
    pending = None
    if SENSITIVITY in suites:
        progress.stage(f"initial analysis: sensitivity and identifiability of {', '.join(parameters)}")
        if isinstance(workers, DaskCluster):  # a cluster takes the analysis and the scenarios at once
            pending = side.submit(initial_analysis, model, list(parameters), window or "moderate", workers=workers)
        else:  # one local pool at a time
            done.analysis = initial_analysis(model, list(parameters), window or "moderate", workers=workers)
    if scenarios:
        total = len(scenarios)
        finished: list[Any] = []
        progress.step(0, total, "scenarios")

        def on_scenario(result: Any) -> None:
            finished.append(result)
            progress.step(len(finished), total, f"scenarios (last: {result.suite} {result.id}, "
                                                f"{result.iterations} iterations)")

        results = run_scenarios(model, list(scenarios), workers=workers, progress=on_scenario)
        for name in suites:
            if name in SCENARIO_SUITES:
                done.suites[name] = [r for r in results if r.suite == name]
    if pending is not None:
        done.analysis = pending.result()
    if done.analysis is not None:
        analysis_files = write_initial_analysis(done.analysis, out, model.name)
        done.summary[SENSITIVITY] = _analysis_summary(done.analysis, analysis_files)
    side.shutdown()
    files_by_suite = {}
    for name, results in done.suites.items():
        progress.stage(f"{name}: tables and figures")
        files_by_suite[name] = write_suite(name, results, out)
        done.summary["suites"][name] = {**suite_summary(results), "files": files_by_suite[name]}
    done.summary["wall_s"] = round(time.perf_counter() - t0, 1)
    progress.stage("writing the report")
    report = write_report(out, case=model.name, command=command, suites=done.suites, files=files_by_suite,
                          analysis=done.analysis, analysis_files=analysis_files, wall_s=done.summary["wall_s"],
                          workers=where, complete=complete)
    done.summary["targets"] = [{"target": t, "measured": row["measured"], "met": row["met"]}
                               for t, row in targets(done.suites, wall_s=done.summary["wall_s"], complete=complete,
                                                     workers=where).iterrows()]
    done.summary["report"] = str(report)
    done.summary = jsonable(done.summary)
    (out / "summary.json").write_text(json.dumps(done.summary, indent=2) + "\n", encoding="utf-8")
    return done


def _analysis_summary(analysis: Any, files: dict) -> dict:
    out = {"parameters": list(analysis.parameters), "window": [t.isoformat() for t in analysis.window],
           "model_runs": analysis.model_runs, "wall_s": round(analysis.wall_s, 1),
           "sensitivity": analysis.sensitivity.summary(), "files": files}
    if analysis.identifiability is not None:
        from rivercal.report.identifiability import summary as explained

        out["identifiability"] = explained(analysis.identifiability)
    return out
