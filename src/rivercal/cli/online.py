"""``rivercal online`` (the on-line service: replay or follow) and ``rivercal report`` (its HTML report).

Observations reach the store from a twin scenario of thesis chapter 5 (``--scenario``), from files
(``--observations``, CSV or Delft-FEWS PI-XML), or from a folder that is watched (``--follow``); the
service then runs every cycle that is due. A restarted command with the same ``--db`` and ``--run``
resumes at the first unfinished cycle.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Any

import typer

from rivercal.cli.common import (
    CaseArg,
    JsonOpt,
    QuietOpt,
    emit_json,
    err_console,
    null_context,
    out_console,
    parse_assignments,
)

__all__ = ["demo", "online", "report"]


def _utc(text: str, what: str):
    import pandas as pd

    try:
        ts = pd.Timestamp(text)
    except ValueError:
        raise ValueError(f"{what} {text!r}: not a date or time") from None
    return ts.tz_localize("UTC") if ts.tzinfo is None else ts.tz_convert("UTC")


def _read_file(path: Path):
    from rivercal.io import read_observations_csv, read_pixml

    if not path.is_file():
        raise ValueError(f"--observations {path}: no such file")
    if path.suffix.lower() == ".xml":
        return read_pixml(path)
    if path.suffix.lower() == ".csv":
        return read_observations_csv(path)
    raise ValueError(f"--observations {path}: expected a .csv or a PI-XML .xml file")


def online(
    case: CaseArg,
    date_from: Annotated[str, typer.Option("--from", help="Issue time of the first cycle (UTC), e.g. 2010-10-18.")],
    date_to: Annotated[str, typer.Option("--to", help="Issue time of the last cycle (UTC), e.g. 2010-11-15.")],
    db: Annotated[Path, typer.Option(help="The SQLite store (created if missing).")] = Path("out/online/run.sqlite"),
    scenario: Annotated[str | None, typer.Option(
        help="Twin observations of a scenario of thesis ch. 5: PI-0, PI-Fg, PI-Wg, PI-Fl, PI-Wl.")] = None,
    observations: Annotated[list[Path], typer.Option(
        "--observations", help="Observation file to ingest (CSV or PI-XML); repeatable.")] = [],  # noqa: B006
    follow: Annotated[Path | None, typer.Option(
        help="Watch this folder for new CSV / PI-XML files and run each cycle when its data are in.")] = None,
    poll: Annotated[float, typer.Option(help="With --follow: seconds between looks at the folder.")] = 10.0,
    run: Annotated[str | None, typer.Option(help="Run name in the store (default: the scenario or 'online').")] = None,
    params: Annotated[str, typer.Option("--params", help="Parameters to estimate.")] = "FA,Wd",
    window: Annotated[str, typer.Option(help="Calibration window length.")] = "7D",
    cycle: Annotated[str, typer.Option(help="Time between cycles.")] = "1D",
    horizon: Annotated[str, typer.Option(help="Forecast horizon.")] = "48h",
    warmup: Annotated[str, typer.Option(
        help="Simulated time before each window whose residuals do not count.")] = "24h",
    algorithm: Annotated[str, typer.Option(help="Optimiser.")] = "dud",
    deadline: Annotated[float, typer.Option(help="Wall-clock limit of one calibration, s.")] = 60.0,
    max_change: Annotated[str | None, typer.Option(
        "--max-change", help="Largest change per cycle, e.g. 'FA=5,Wd=0.1' (default: none).")] = None,
    alert_k: Annotated[float, typer.Option("--alert-k", help="Alert when an estimate moves more than k σ.")] = 3.0,
    noise: Annotated[str, typer.Option(help="Twin noise of --scenario: none, white, gaussian or pink.")] = "none",
    seed: Annotated[int, typer.Option(help="Seed of the twin noise.")] = 0,
    max_cycles: Annotated[int | None, typer.Option("--max-cycles", help="Stop after this many cycles.")] = None,
    workers: Annotated[int | None, typer.Option(help="Worker processes per calibration (default: all cores).")] = None,
    out: Annotated[Path | None, typer.Option(help="Write the report and exports into this folder.")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Run the on-line service: every cycle re-estimates the parameters and forecasts against the DSS."""
    from rivercal.model import load_model
    from rivercal.online.service import OnlineConfig, OnlineService
    from rivercal.store import Store

    first, last = _utc(date_from, "--from"), _utc(date_to, "--to")
    if not last >= first:
        raise ValueError(f"--to {date_to} is before --from {date_from}")
    if scenario is not None:
        from rivercal.twin.practical import PRACTICAL_SCENARIOS

        if scenario not in PRACTICAL_SCENARIOS:
            raise ValueError(f"--scenario {scenario!r}: unknown practical scenario; choose one of "
                             f"{', '.join(PRACTICAL_SCENARIOS)}")
    if scenario is not None and (observations or follow is not None):
        raise ValueError("--scenario makes twin observations; it does not combine with --observations or --follow")
    if follow is not None and not follow.is_dir():
        raise ValueError(f"--follow {follow}: no such folder")
    if not poll > 0:
        raise ValueError(f"--poll {poll}: must be positive")
    files = [_read_file(p) for p in observations]  # bad files fail before any model run
    config = OnlineConfig(parameters=tuple(n.strip() for n in params.split(",") if n.strip()), window=window,
                          period=cycle, horizon=horizon, warmup=warmup, algorithm=algorithm, deadline_s=deadline,
                          max_change=parse_assignments(max_change, "--max-change"), alert_k=alert_k, workers=workers)
    show = not (quiet or as_json)
    name = run or scenario or "online"
    meta: dict[str, Any] = {"scenario": scenario, "noise": noise, "seed": seed} if scenario else {}
    db.parent.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    status = err_console.status("loading the model", spinner="dots") if show else null_context()
    with status, Store(db) as store:
        model = load_model(case)
        service = OnlineService(model, store, name, config, first, meta=meta)
        if scenario is not None:
            from rivercal.twin.practical import practical_truth

            if show:
                status.update(f"{scenario}: running the truth")
            truth = practical_truth(model, scenario, *service.data_period(last), noise=noise, seed=seed,
                                    series=service.series)
            store.ingest(truth.observations, source=f"twin:{scenario}")
        for path, obs in zip(observations, files, strict=True):
            store.ingest(obs, source=path.name)
        outcomes = []
        units = {p.name: p.unit for p in model.case.spec.parameters}

        def progress(o) -> None:
            outcomes.append(o)
            if show:
                values = ", ".join(f"{k} {_fmt(v, units.get(k, ''))}" + ("*" if k in o.held else "")
                                   for k, v in o.accepted.items())
                status.update(f"cycle {o.cycle} ({o.issue_time:%Y-%m-%d %H:%M}): {o.status}, {values}")
                err_console.print(f"cycle {o.cycle:>3} {o.issue_time:%Y-%m-%d %H:%M}  {o.status:<7} {values}  "
                                  f"{o.model_runs} runs {o.wall_s:.1f} s"
                                  + "".join(f"\n    [yellow]{a.kind}[/]: {a.message}" for a in o.alerts),
                                  highlight=False)

        if follow is None:
            service.replay(last, progress=progress, max_cycles=max_cycles)
        else:
            _follow(service, store, follow, last, poll, progress, max_cycles, status if show else None)
        summary = online_summary(store, service, outcomes, time.perf_counter() - t_start)
        if out is not None:
            from rivercal.report.online import write_online_report

            if show:
                status.update("writing the report")
            summary["files"] = write_online_report(store, service.run.name, out, model=model)
    if as_json:
        emit_json(summary)
    elif not quiet:
        print_summary(summary)


def _follow(service, store, folder: Path, last, poll: float, progress, max_cycles, status) -> None:
    """Ingest new files from ``folder`` and run each cycle when the newest data reach its issue time."""
    seen: dict[Path, tuple[float, int]] = {}
    done = 0
    try:
        while True:
            for path in sorted(folder.iterdir()):
                if path.suffix.lower() not in (".csv", ".xml") or not path.is_file():
                    continue
                stamp = (path.stat().st_mtime, path.stat().st_size)
                if seen.get(path) == stamp:
                    continue
                try:
                    store.ingest(_read_file(path), source=path.name)
                except ValueError as exc:  # a bad file is reported and skipped; the service goes on
                    err_console.print(f"[bold red]skipped[/] {path.name}: {exc}", highlight=False)
                seen[path] = stamp
            newest = service.latest_observation()
            while newest is not None and (max_cycles is None or done < max_cycles):
                spec = service.next_cycle(now=min(newest, last))
                if spec is None:
                    break
                progress(service.run_cycle(spec))
                done += 1
            nxt = service.next_cycle()
            if nxt is None or nxt.issue_time > last or (max_cycles is not None and done >= max_cycles):
                return
            if status is not None:
                status.update(f"waiting for observations up to {nxt.issue_time:%Y-%m-%d %H:%M} in {folder}")
            time.sleep(poll)
    except KeyboardInterrupt:
        err_console.print("stopped; the store holds every finished cycle, a restart resumes after the last one")


def online_summary(store, service, outcomes, wall: float) -> dict[str, Any]:
    """JSON-friendly summary of a run: cycles, estimates, alerts and forecast errors (updated vs DSS)."""
    from rivercal.report.online import forecast_errors

    cycles = store.cycles(service.run)
    est = store.estimates(service.run)
    alerts = store.alerts(service.run)
    errors = forecast_errors(store, service.run)
    return {
        "run": service.run.name,
        "case": service.model.case.name,
        "db": str(store.path),
        "cycles_done_now": len(outcomes),
        "cycles": len(cycles),
        "status": cycles["status"].value_counts().to_dict(),
        "wall_s": round(wall, 2),
        "units": {p.name: p.unit for p in service.parameters},
        "cycle_wall_s_median": float(cycles["wall_time_s"].median()) if len(cycles) else None,
        "model_runs_median": float(cycles["model_runs"].median()) if len(cycles) else None,
        "estimates": [
            {"cycle": int(c), "issue_time": g["issue_time"].iloc[0].isoformat(),
             **{r.parameter: float(r.value) for r in g.itertuples()},
             "held": [r.parameter for r in g.itertuples() if not r.accepted]}
            for c, g in est.groupby("cycle")],
        "alerts": [{"cycle": int(r.cycle), "kind": r.kind, "parameter": r.parameter, "message": r.message}
                   for r in alerts.itertuples()],
        "forecast_errors": errors,
    }


def print_summary(summary: dict[str, Any]) -> None:
    """The short printed summary: estimates per cycle, alerts, forecast error vs the DSS, where the report is."""
    from rich.table import Table

    table = Table(title=f"run {summary['run']} ({summary['case']}): {summary['cycles']} cycles", title_justify="left")
    names = [k for k in (summary["estimates"][0] if summary["estimates"] else {}) if k not in
             ("cycle", "issue_time", "held")]
    for col in ("cycle", "issue time", *names):
        table.add_column(col, justify="right")
    for e in summary["estimates"]:
        table.add_row(str(e["cycle"]), e["issue_time"][:16].replace("T", " "),
                      *[_fmt(e[n], summary["units"].get(n, "")) + (" (held)" if n in e["held"] else "")
                        for n in names])
    out_console.print(table)
    for a in summary["alerts"]:
        out_console.print(f"[yellow]alert[/] cycle {a['cycle']} {a['kind']}: {a['message']}", highlight=False)
    fe = summary["forecast_errors"]
    if fe.get("n"):
        out_console.print(f"forecast level error (mean |error| over {fe['n']} values at the stations, lead 0-"
                          f"{fe['lead_h']:g} h): rivercal {fe['updated_mae_m'] * 100:.2f} cm, fixed DSS "
                          f"{fe['dss_mae_m'] * 100:.2f} cm" + _ratio_words(fe.get("ratio")), highlight=False)
    elif fe.get("reason"):
        out_console.print("forecast level error, rivercal against the fixed DSS: nothing to compare yet — "
                          + fe["reason"], highlight=False)
    if "files" in summary:
        out_console.print(f"report: {summary['files']['report']}")


def _ratio_words(ratio: float | None) -> str:
    if not ratio:
        return ""
    return " (more than 1000× smaller)" if ratio > 1000 else f" ({ratio:.1f}× smaller)"


def _fmt(value: float, unit: str) -> str:
    """A parameter value to the precision that matters: 0.1 mm for levels, 0.01 for the rest."""
    return f"{value:.4f}" if unit in ("m", "m AD") else f"{value:.2f}"


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
    and forecasts 48 h ahead beside the DSS, whose friction stays 16.
    """
    db = out / "run.sqlite"
    if not resume:
        for suffix in ("", "-wal", "-shm"):
            Path(f"{db}{suffix}").unlink(missing_ok=True)
    online(case="dommel", date_from="2010-10-18", date_to="2010-11-15", db=db, scenario="PI-Fg", observations=[],
           follow=None, poll=10.0, run="demo-PI-Fg", params="FA,Wd", window="7D", cycle="1D", horizon="48h",
           warmup="24h", algorithm="dud", deadline=60.0, max_change=None, alert_k=3.0, noise="none", seed=0,
           max_cycles=None, workers=workers, out=out / "report", as_json=as_json, quiet=False)


def report(
    db: Annotated[Path, typer.Option(help="The SQLite store of an on-line run.")],
    out: Annotated[Path, typer.Option(help="Folder for the report (index.html, figures, CSV).")],
    run: Annotated[str | None, typer.Option(help="Run name (default: the only run, or the latest).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Write the HTML report of an on-line run from its store: tables, figures and the DSS comparison."""
    from rivercal.model import load_model
    from rivercal.report.online import write_online_report
    from rivercal.store import Store

    if not db.is_file():
        raise ValueError(f"--db {db}: no such store")
    with Store(db, readonly=True) as store:
        runs = store.runs()
        if runs.empty:
            raise ValueError(f"--db {db}: the store holds no run")
        name = run if run is not None else str(runs.sort_values("created")["name"].iloc[-1])
        stored = store.get_run(name)
        if stored is None:
            raise ValueError(f"--run {name!r}: not in {db} (it has {', '.join(runs['name'])})")
        files = write_online_report(store, name, out, model=load_model(stored.case))
    if as_json:
        emit_json({"run": name, "files": files})
    else:
        out_console.print(f"report: {files['report']}")
