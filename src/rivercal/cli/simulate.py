"""``rivercal simulate``: run a case and write its station series (CSV, CF-1.8 NetCDF, optionally a figure)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rivercal.cli.common import CaseArg, JsonOpt, QuietOpt, Reporter, emit_json, out_console
from rivercal.cli.options import open_model, output_dir, parse_sets, parse_time

__all__ = ["compile_engine", "simulate"]


def simulate(
    case: CaseArg,
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/simulate"),
    set_: Annotated[list[str], typer.Option("--set", help="Model quantity NAME=VALUE, e.g. friction:global=20 or "
                                                          "weir:ZL1-3014.crest_level=10.3; repeatable.")] = [],  # noqa: B006
    start: Annotated[str | None, typer.Option(help="Start (UTC, ISO 8601); default: the case start.")] = None,
    end: Annotated[str | None, typer.Option(help="End (UTC, ISO 8601); default: the case end.")] = None,
    plot: Annotated[bool, typer.Option("--plot", help="Also draw series.png (adds ~1.5 s).")] = False,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Run a case and write series.csv and series.nc (CF-1.8); with --plot also a hydrograph figure."""
    from rivercal.errors import OptionError
    from rivercal.workflows.simulate import simulate_case

    parse_sets(set_)
    t0 = parse_time(start, "--start") if start is not None else None
    t1 = parse_time(end, "--end") if end is not None else None
    output_dir(out)
    model = open_model(case, show_compilation=not quiet)
    quantities = parse_sets(set_, model)
    a, b = t0 or model.start, t1 or model.end
    for option, t in (("--start", t0), ("--end", t1)):
        if t is not None and not model.start <= t <= model.end:
            raise OptionError(f"{option} {t:%Y-%m-%d %H:%M}: outside the case period {model.start:%Y-%m-%d %H:%M} .. "
                              f"{model.end:%Y-%m-%d %H:%M}", option=option)
    if not b > a:
        raise OptionError(f"--end {b:%Y-%m-%d %H:%M} is not after --start {a:%Y-%m-%d %H:%M}", option="--end")
    step = float(getattr(getattr(model, "settings", None), "output_interval", 0) or 0)
    if step and (b - a).total_seconds() % step:
        raise OptionError(f"--start/--end: the period {a:%Y-%m-%d %H:%M:%S} .. {b:%Y-%m-%d %H:%M:%S} is not a multiple "
                          f"of the case's output interval ({step:g} s)", option="--end")
    reporter = Reporter(not (quiet or as_json))
    with reporter.running(f"simulating {model.name}"):
        summary = simulate_case(model, quantities, out, start=a, end=b, plot=plot, progress=reporter)
    if as_json:
        emit_json(summary)
    elif not quiet:
        balance = summary["volume_balance_relative_error"]
        out_console.print(f"simulated [bold]{summary['case']}[/] {a:%Y-%m-%d %H:%M} .. {b:%Y-%m-%d %H:%M} UTC in "
                          f"{summary['wall_s']:.2f} s"
                          + (f" (volume balance error {balance:.1e})" if balance is not None else ""))
        for key, short in summary["shortfalls"].items():
            out_console.print(f"[yellow]warning:[/] {key} ran short of water: {short['requested_m3']:.6g} m³ asked, "
                              f"{short['delivered_m3']:.6g} m³ delivered")
        divided = summary["run"].get("divided_steps", 0)
        if divided:
            out_console.print(f"{divided} time steps were too long for the flow and were divided (into up to "
                              f"{summary['run']['max_division']} sub-steps)")
        out_console.print("wrote " + ", ".join(summary["files"].values()))
        out_console.print(f"next: compare series.csv with your gauges; `rivercal calibrate {case} --help` estimates "
                          f"the parameters over a window and `rivercal online {case} --help` runs the daily service",
                          highlight=False)


def compile_engine(as_json: JsonOpt = False) -> None:
    """Compile the engine and the rainfall-runoff model now (about a minute, once per machine and version).

    Later runs start at once, and say nothing of compiling.
    """
    import time

    from rivercal.case import load_case
    from rivercal.engine.warmup import VARIANTS
    from rivercal.engine.warmup import compile_engine as compile_variants
    from rivercal.hydrology import _kernels as runoff_kernels
    from rivercal.hydrology.catchments import catchment_forcing

    ready = compile_variants()
    # the rainfall-runoff model of the packaged case, as every run of a case with catchments calls it
    t0 = time.perf_counter()
    catchment_forcing(load_case("dommel"))
    runoff = {"case": "dommel", "seconds": round(time.perf_counter() - t0, 2),
              "from_cache": not sum(runoff_kernels.run_walrus.stats.cache_misses.values())}
    if as_json:
        emit_json({**{variant: {"case": VARIANTS[variant], "seconds": round(r.seconds, 2), "from_cache": r.from_cache}
                      for variant, r in ready.items()}, "rainfall-runoff": runoff})
        return
    for variant, r in ready.items():
        how = "loaded from the cache" if r.from_cache else "compiled"
        out_console.print(f"time loop {variant} (case {VARIANTS[variant]}): {how} in {r.seconds:.1f} s",
                          highlight=False)
    how = "loaded from the cache" if runoff["from_cache"] else "compiled"
    out_console.print(f"rainfall-runoff model (case dommel): {how} in {runoff['seconds']:.1f} s", highlight=False)
