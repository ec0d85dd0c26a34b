"""``rivercal online`` (the on-line service, replay or follow), ``rivercal report`` and ``rivercal demo``.

The work is :func:`rivercal.workflows.online.run_online`'s; this module checks the options and prints.
A restarted command with the same ``--db`` and ``--run`` resumes at the first unfinished cycle.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import typer

from rivercal.cli.common import (
    CaseArg,
    DaskOpt,
    DependencyOpt,
    DependencyThresholdOpt,
    JsonOpt,
    QuietOpt,
    Reporter,
    emit_json,
    out_console,
)
from rivercal.cli.options import (
    check_choice,
    check_number,
    check_workers,
    dask_address,
    open_model,
    output_dir,
    output_file,
    parse_time,
    read_observations,
    workers_for,
)
from rivercal.errors import CaseError, OptionError, RivercalError

__all__ = ["demo", "online", "print_summary", "report"]


def online(
    case: CaseArg,
    date_from: Annotated[str, typer.Option("--from", help="Issue time of the first cycle (UTC), e.g. 2010-10-18.")],
    date_to: Annotated[str, typer.Option("--to", help="Issue time of the last cycle (UTC), e.g. 2010-11-15.")],
    db: Annotated[str, typer.Option(
        help="The store: an SQLite file (created if missing) or a postgresql://USER@HOST/DB URL (SQLite is the "
             "embedded default).")] = "out/online/run.sqlite",
    scenario: Annotated[str | None, typer.Option(
        help="Twin observations of a scenario of thesis ch. 5: PI-0, PI-Fg, PI-Wg, PI-Fl, PI-Wl; of the "
        "controlled case: PI-SF.")] = None,
    observations: Annotated[list[Path], typer.Option(
        "--observations", help="Observation file to ingest (CSV, PI-XML, or a sidecar TOML describing gauge files); "
                                "repeatable.")] = [],  # noqa: B006
    follow: Annotated[Path | None, typer.Option(
        help="Watch this folder for new CSV / PI-XML files and run each cycle when its data are in.")] = None,
    poll: Annotated[float, typer.Option(help="With --follow: seconds between looks at the folder.")] = 10.0,
    run: Annotated[str | None, typer.Option(help="Run name in the store (default: the scenario or 'online').")] = None,
    params: Annotated[str, typer.Option("--params", help="Parameters to estimate.")] = "FA,Wd",
    window: Annotated[str, typer.Option(help="Calibration window length, e.g. 7D.")] = "7D",
    cycle: Annotated[str, typer.Option(help="Time between cycles, e.g. 1D.")] = "1D",
    horizon: Annotated[str, typer.Option(help="Forecast horizon, e.g. 48h.")] = "48h",
    warmup: Annotated[str, typer.Option(
        help="Simulated time before each window whose residuals do not count, e.g. 24h.")] = "24h",
    algorithm: Annotated[str, typer.Option(help="Optimiser.")] = "dud",
    deadline: Annotated[float, typer.Option(help="Wall-clock limit of one calibration, s.")] = 60.0,
    dependency: DependencyOpt = None,
    dependency_threshold: DependencyThresholdOpt = 0.1,
    max_change: Annotated[str | None, typer.Option(
        "--max-change", help="Largest change per cycle, e.g. 'FA=5,Wd=0.1' (default: none).")] = None,
    sigma: Annotated[str | None, typer.Option(
        "--sigma", help="Observation error σ per quantity or series, e.g. 'Q=50' or 'h=0.05,0040.Q=2' (m, m³/s; "
                        "default h=0.025, Q=0.1): the weights of the calibrations and the errors of the state "
                        "analyses.")] = None,
    alert_k: Annotated[float, typer.Option(
        "--alert-k", help="An estimate that moves more than k σ and its resolution jumps: a jump starts the "
                           "transition estimator, and a transition it finds raises one jump alert.")] = 3.0,
    loss: Annotated[str, typer.Option(help="Cost of the calibrations: huber, student-t or l2.")] = "huber",
    transition: Annotated[bool, typer.Option(
        help="Look for a transition after each jump and carry its value after (--no-transition: every jump raises "
             "a jump alert and the estimate creeps).")] = True,
    skill_cycles: Annotated[int, typer.Option(
        "--skill-cycles", help="Do no harm: issue the DSS's forecast while the updated one scored worse over this "
                               "many recent cycles (0: always the updated one).")] = 3,
    noise: Annotated[str, typer.Option(help="Twin noise of --scenario: none, white, gaussian or pink.")] = "none",
    seed: Annotated[int, typer.Option(help="Seed of the twin noise and the realism errors (≥ 0).")] = 0,
    realism: Annotated[str | None, typer.Option(
        help="Errors of the twin of --scenario: ideal, noisy, realistic, realistic-forcing (realistic without "
             "the structural error), or a TOML file of error models (docs/realism.md).")] = None,
    max_cycles: Annotated[int | None, typer.Option("--max-cycles", help="Stop after this many cycles.")] = None,
    assimilate: Annotated[str | None, typer.Option(
        help="What the service updates: parameters (daily), states (ensemble Kalman filter, hourly) or both (default "
             "where the model can update its states, else parameters).")] = None,
    members: Annotated[int, typer.Option(help="With --assimilate states|both: ensemble members.")] = 64,
    ensemble_filter: Annotated[str, typer.Option(
        "--filter", help="With --assimilate states|both: etkf (square root) or enkf (perturbed observations).")]
    = "etkf",
    issued: Annotated[str, typer.Option(
        "--issue", help="With --assimilate states|both, the forecast issued: mean (of the members' forecasts) or "
                        "central (one more run from the members' mean state and expected inflow errors: no bias "
                        "from the members' spread, e.g. on a large river).")] = "mean",
    rain_error: Annotated[float, typer.Option(
        "--rain-error", help="Twin of --scenario: error of the inflows and laterals, e.g. 0.3 for about 30 %.")] = 0.0,
    workers: Annotated[int | None, typer.Option(help="Worker processes per calibration (default: all cores).")] = None,
    dask: DaskOpt = None,
    out: Annotated[Path | None, typer.Option(help="Write the report and exports into this folder.")] = None,
    take_over: Annotated[bool, typer.Option(
        "--take-over", help="Resume a cycle that the store says a live process computes: after a reboot or a "
                            "container restart another program may have the dead service's process id. Only when "
                            "no other service runs this run.")] = False,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Run the on-line service: every cycle re-estimates the parameters and forecasts against the DSS."""
    from rivercal.models.capabilities import require
    from rivercal.online.assimilation import (
        ASSIMILATE_MODES,
        ISSUED,
        NEEDS,
        AssimilationConfig,
        can_update_states,
        default_mode,
    )
    from rivercal.twin import NOISE_MODELS
    from rivercal.twin.practical import SCENARIOS
    from rivercal.workflows.online import run_online

    # -- everything is checked before the first model run: first what needs no case
    first, last = parse_time(date_from, "--from"), parse_time(date_to, "--to")
    if not last >= first:
        raise OptionError(f"--to {date_to}: before --from {date_from}", option="--to")
    if scenario is not None:
        check_choice(scenario, "--scenario", SCENARIOS, "practical scenario")
        if observations or follow is not None:
            raise OptionError("--scenario makes twin observations; it does not combine with --observations or "
                              "--follow", option="--scenario")
    check_choice(noise, "--noise", NOISE_MODELS)
    if noise != "none" and scenario is None:
        raise OptionError("--noise applies to the twin observations of --scenario only", option="--noise")
    level = None
    if realism is not None:
        from rivercal.twin.realism import get_realism

        if scenario is None:
            raise OptionError("--realism applies to the twin of --scenario only", option="--realism")
        try:
            level = get_realism(realism)
        except ValueError as exc:
            raise OptionError(f"--realism {realism}: {exc}", option="--realism") from None
        if noise != "none" and not level.ideal:
            raise OptionError(f"--noise {noise} and --realism {realism} both add observation errors; the realism "
                              "level has its own sensor noise", option="--noise")
    if follow is not None and not follow.is_dir():
        raise OptionError(f"--follow {follow}: no such folder", option="--follow")
    check_number(poll, "--poll", low=0, low_open=True)
    # the configuration's own checks (rivercal.online.config), each problem named by its option
    settings = {"parameters": params, "window": window, "period": cycle, "horizon": horizon, "warmup": warmup,
                "algorithm": algorithm, "deadline_s": deadline, "max_change": max_change, "sigma": sigma,
                "alert_k": alert_k, "loss": loss, "transition": transition, "skill_cycles": skill_cycles,
                "dependency": str(dependency) if dependency is not None else None,
                "dependency_threshold": dependency_threshold}
    config = _config(None, settings)
    check_number(seed, "--seed", low=0)
    check_number(max_cycles, "--max-cycles", low=1)
    if assimilate is not None:
        check_choice(assimilate, "--assimilate", ASSIMILATE_MODES)
    check_number(members, "--members", low=2, high=10_000)
    check_choice(ensemble_filter, "--filter", ("etkf", "enkf"))
    check_choice(issued, "--issue", ISSUED)
    check_number(rain_error, "--rain-error", low=0, high=2)
    if rain_error and scenario is None:
        raise OptionError("--rain-error applies to the twin observations of --scenario only", option="--rain-error")
    check_workers(workers)
    address = dask_address(dask, workers)
    files = [(p.name, read_observations(p)) for p in observations]
    db = _store_file(db, "--db")
    if out is not None:
        output_dir(out)
    # -- then what needs the case
    model = open_model(case, show_compilation=not quiet)
    config = _config(model, settings)
    mode = assimilate if assimilate is not None else default_mode(model)
    if mode != "parameters" and not can_update_states(model):
        try:
            require(model, *NEEDS, purpose=f"--assimilate {mode}")
        except ValueError as exc:
            raise OptionError(f"{exc}; use --assimilate parameters", option="--assimilate") from None
    check_times(model, config, first, last, {"first": date_from, "last": date_to})
    reporter = Reporter(not (quiet or as_json))
    from rivercal.store import RunMismatchError

    name = run or scenario or "online"
    with reporter.running("starting"), workers_for(workers, address) as where:
        config = replace(config, workers=where)
        from rivercal.models.load import model_source

        try:
            summary = run_online(model, db, name, config, first, last, scenario=scenario,
                                 noise=noise, seed=seed, realism=level, observations=files, follow=follow, poll=poll,
                                 max_cycles=max_cycles, report=out, progress=reporter,
                                 assimilation=AssimilationConfig(mode=mode, members=members, method=ensemble_filter,
                                                                 seed=seed, issued=issued),
                                 rain_error=rain_error, take_over=take_over,
                                 source=model_source(case))
        except RunMismatchError as exc:  # the options against the stored run: bad input, exit status 2
            raise OptionError(f"--run {name}: {exc}, or the options it was started with (--run names a run, "
                              "default: the scenario or 'online')", option="--run") from None
    summary["final_state"] = _final_state(summary)
    if as_json:
        emit_json(summary)
    elif not quiet:
        print_summary(summary)
    if summary["cycles_done_now"] and not summary["cycles_succeeded_now"]:
        raise NoCycleSucceeded(summary)


def _final_state(summary: dict[str, Any]) -> list[str]:
    """Where the run ends, read back from its store (:func:`rivercal.report.online_figures.final_state_lines`)."""
    from rivercal.report.online_figures import final_state_lines
    from rivercal.store import Store

    with Store(summary["db"], readonly=True) as store:
        return final_state_lines(store, summary["run"])


#: The option that sets each field of the on-line configuration (for the messages of its checks).
_OPTION_OF = {"parameters": "--params", "window": "--window", "period": "--cycle", "horizon": "--horizon",
              "warmup": "--warmup", "algorithm": "--algorithm", "deadline_s": "--deadline",
              "max_change": "--max-change", "sigma": "--sigma", "alert_k": "--alert-k", "loss": "--loss",
              "skill_cycles": "--skill-cycles",
              "dependency": "--dependency", "dependency_threshold": "--dependency-threshold", "workers": "--workers"}


def _config(model: Any, settings: dict[str, Any]) -> Any:
    """:meth:`rivercal.online.config.OnlineConfig.from_options`; a problem is named by its option."""
    from rivercal.online.config import OnlineConfig, OnlineConfigError

    try:
        return OnlineConfig.from_options(model, **settings)
    except OnlineConfigError as exc:
        option = _OPTION_OF.get(exc.field, f"--{exc.field.replace('_', '-')}")
        raise OptionError(exc.describe(option), option=option) from None


class NoCycleSucceeded(RivercalError):
    """Cycles ran, and none of them ended ``done``: exit status 1, with what the cycles said."""

    def __init__(self, summary: dict[str, Any]):
        n = summary["cycles_done_now"]
        kinds = ", ".join(f"{v} {k}" for k, v in sorted(summary.get("status_now", {}).items()))
        first = summary.get("first_message_now") or ""
        super().__init__(f"no cycle succeeded: {'the' if n > 1 else 'the one'} cycle{'s' if n > 1 else ''} run now "
                         f"{'all ' if n > 1 else ''}ended without an estimate ({kinds or n}); the first said: "
                         f"{first}. They are stored in {summary['db']} (run {summary['run']!r}) with the last "
                         "accepted estimates kept")


#: The options that set the times of an on-line run, by the setting they set (for the messages of the checks).
_TIME_OPTIONS = {"window": "--window", "period": "--cycle", "horizon": "--horizon", "warmup": "--warmup",
                 "first": "--from", "last": "--to"}


def check_times(model: Any, config: Any, first: Any, last: Any, shown: dict[str, str]) -> None:
    """The times of the run against the model (:func:`rivercal.online.config.check_schedule`), named by option."""
    from rivercal.online.config import check_schedule

    try:
        check_schedule(model, config, first, last, names=_TIME_OPTIONS, shown=shown)
    except ValueError as exc:
        text = str(exc)
        option = next((o for o in _TIME_OPTIONS.values() if text.startswith(o + " ")), "--window")
        raise OptionError(text, option=option) from None


def _store_file(db: str | Path, option: str, *, must_exist: bool = False) -> str | Path:
    """A store: a PostgreSQL URL as it is, or a file that is absent (it is created) or an SQLite file."""
    from rivercal.store import is_url

    if is_url(db):
        return str(db)
    db = Path(db)
    if must_exist:  # read only: the store may lie where nothing can be written (a read-only mount)
        if not db.is_file():
            raise OptionError(f"{option} {db}: {'is a folder, not a store' if db.is_dir() else 'no such store'}",
                              option=option)
        if db.stat().st_size == 0:
            raise OptionError(f"{option} {db}: an empty file, not a store (no run was ever written to it)",
                              option=option)
    else:
        output_file(db, option)
    if db.is_file() and db.stat().st_size > 0:
        with db.open("rb") as fh:
            if fh.read(16) != b"SQLite format 3\x00":
                raise OptionError(f"{option} {db}: not a store (not an SQLite file)", option=option)
    return db


def print_summary(summary: dict[str, Any]) -> None:
    """The short printed summary: estimates per cycle, alerts, forecast error vs the DSS, where the report is."""
    from rich.table import Table

    from rivercal.workflows.online import format_value

    table = Table(title=f"run {summary['run']} ({summary['case']}): {summary['cycles']} cycles", title_justify="left")
    names = [k for k in (summary["estimates"][0] if summary["estimates"] else {}) if k not in
             ("cycle", "issue_time", "held")]
    issued = {i["cycle"]: i["issued"] or "-" for i in summary.get("issued", [])}
    for col in ("cycle", "issue time", *names, "forecast issued"):
        table.add_column(col, justify="right")
    for e in summary["estimates"]:
        table.add_row(str(e["cycle"]), e["issue_time"][:16].replace("T", " "),
                      *[format_value(e[n], summary["units"].get(n, "")) + (" (held)" if n in e["held"] else "")
                        for n in names], issued.get(e["cycle"], "-"))
    out_console.print(table)
    for a in summary["alerts"]:
        out_console.print(f"[yellow]alert[/] cycle {a['cycle']} {a['kind']}: {a['message']}", highlight=False)
    _print_figures(summary)
    for line in summary.get("final_state") or []:
        out_console.print(line, highlight=False)
    if "files" in summary:
        out_console.print(f"report: {summary['files']['report']} (open it in a browser)", highlight=False)
    out_console.print(f"next: `rivercal dashboard --db {summary['db']}` shows the run in a browser on "
                      "http://127.0.0.1:8050/ (the forecast page, the estimates, the alerts); docs/explanation/"
                      "alerts-and-decisions.md says what each word means", highlight=False)


def _print_figures(summary: dict[str, Any]) -> None:
    """The headline figures in the words of the report and the dashboard (report.online_figures.headline_lines)."""
    from rivercal.report.online_figures import headline_lines

    for line in headline_lines(summary):
        out_console.print(line, highlight=False)
    out_console.print(updated_words(summary.get("assimilate", "parameters"), summary.get("state_updating_failed"),
                                    summary.get("cycles")), highlight=False)


def updated_words(mode: str, failed: list[int] | None = None, cycles: int | None = None) -> str:
    """What the run updated, in words: the states at every hourly forecast step, the parameters every cycle.

    ``failed`` lists the cycles whose state updating failed (of ``cycles``): their updated forecast is the parameters'
    own.
    """
    what = {"both": "states (hourly, ensemble Kalman filter) and parameters (every cycle)", "states": "states only",
            "parameters": "parameters only"}.get(mode, mode)
    text = f"Updated: {what}."
    if failed:
        listed = ", ".join(map(str, failed[:5])) + (" …" if len(failed) > 5 else "")
        text += (f" The state updating failed in {len(failed)} of {cycles or len(failed)} cycles ({listed}: every "
                 "member of the ensemble failed; the cycle log says why): their updated forecast is the parameters' "
                 "own, without state updating or band.")
    return text


def demo(
    out: Annotated[Path, typer.Option("--out", help="Output folder (store, report).")] = Path("out/demo"),
    resume: Annotated[bool, typer.Option(help="Continue the store of an earlier demo instead of starting anew.")]
    = False,
    workers: Annotated[int | None, typer.Option(help="Worker processes per calibration (default: all cores).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """The main job on the embedded default case: scenario PI-Fg on-line over four weeks, the report, a summary.

    The De Dommel-like network's global friction jumps 16 → 25 m^(1/3)/s on 2010-11-01 (vegetation mowed,
    thesis §5-2-1); the service re-estimates friction and crest shift daily from 2010-10-18 to 2010-11-15
    and forecasts 48 h ahead beside the DSS, whose friction stays 16. The truth is ``realistic``
    (docs/realism.md): sensor noise, gaps, spikes and a drifting gauge, rainfall and runoff errors and a
    finer grid with per-branch friction, so the figures are not those of an identical twin.
    """
    output_dir(out)
    db = out / "run.sqlite"
    if not resume:
        for suffix in ("", "-wal", "-shm"):
            Path(f"{db}{suffix}").unlink(missing_ok=True)
    online(case="dommel", date_from="2010-10-18", date_to="2010-11-15", db=db, scenario="PI-Fg", observations=[],
           follow=None, poll=10.0, run="demo-PI-Fg", params="FA,Wd", window="7D", cycle="1D", horizon="48h",
           warmup="24h", algorithm="dud", deadline=60.0, max_change=None, alert_k=3.0, loss="huber", transition=True,
           skill_cycles=3, noise="none", seed=0, realism="realistic", max_cycles=None, workers=workers, dask=None,
           out=out / "report", take_over=False, as_json=as_json, quiet=False)


def report(
    db: Annotated[str, typer.Option(
        help="The store of an on-line run: an SQLite file or a postgresql://USER@HOST/DB URL.")],
    out: Annotated[Path, typer.Option(help="Folder for the report (index.html, figures, CSV).")],
    run: Annotated[str | None, typer.Option(help="Run name (default: the only run, or the latest).")] = None,
    case: Annotated[str | None, typer.Option(
        help="The run's model: a case folder, a packaged case or a model.toml (default: the model the store names; "
             "the store knows an imported model by its name, not by its folder).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Write the HTML report of an on-line run from its store: tables, figures and the DSS comparison."""
    from rivercal.report.online import write_online_report
    from rivercal.store import Store

    db = _store_file(db, "--db", must_exist=True)
    output_dir(out)
    with Store(db, readonly=True) as store:
        runs = store.runs()
        if runs.empty:
            raise OptionError(f"--db {db}: the store holds no run", option="--db")
        name = run if run is not None else str(runs.sort_values("created")["name"].iloc[-1])
        stored = store.get_run(name)
        if stored is None:
            raise OptionError(f"--run {name!r}: not in {db} (it has {', '.join(runs['name'])})", option="--run")
        recorded = stored.config.get("model_source")  # where the model lay when the run was created
        given = case
        if case is None and recorded and Path(recorded).exists():
            case = recorded
        try:
            model = open_model(case if case is not None else stored.case)
        except CaseError:
            if case is not None or Path(stored.case).exists():
                raise  # a case that is there but wrong: its own error names the file and field
            where = f" (it lay at {recorded} when the run was created)" if recorded else ""
            raise OptionError(f"--db {db}: run {name!r} serves the model {stored.case!r}, which is neither a folder "
                              f"here nor a packaged case{where}: give its case folder or model.toml with --case",
                              option="--case") from None
        if model.name != stored.case:
            where = f"--case {case}" if given is not None else f"{case} (the folder run {name!r} recorded)"
            raise OptionError(f"{where}: that is the model {model.name!r}; run {name!r} of {db} serves "
                              f"{stored.case!r} (give its folder with --case)", option="--case")
        files = write_online_report(store, name, out, model=model)
    if as_json:
        emit_json({"run": name, "files": files})
    else:
        out_console.print(f"report: {files['report']}")
