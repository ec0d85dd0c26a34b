"""The embedded engine beside EPA SWMM on one network: a chain of free weirs (``rivercal bench engines``).

:func:`weir_chain_case` builds the network of the engine benchmark's kind: one trapezoidal channel
(bed width 5 m, banks 1:1.5, bed slope 5·10⁻⁴, k_s = 30 m^(1/3)/s) with ``weirs`` broad-crested weirs
(4 m wide, crest 1.8 m above the bed) spread along it, a discharge at the upstream end (steady, or a
flood wave 2 → 6 → 2 m³/s) and a fixed level at the outlet. The weirs stay free at every discharge of
the wave (the level below a weir is the channel's normal depth, below its crest). A station at every
weir observes the levels up- and downstream and the discharge.

:func:`compare_engines` runs the embedded engine and SWMM (the same network written by
:func:`rivercal.models.swmm.convert.case_to_inp`) in one process and returns their station series and
wall times; :func:`bench_engines` is the benchmark (one simulated week, embedded Δt = 60 s, SWMM routing
step 10 s with variable steps, medians of several runs); :func:`refinement` runs the flood wave on both
engines at halved Δx and Δt and says how each converges.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case import case_from_dict
from rivercal.models import EmbeddedModel
from rivercal.models.swmm.convert import case_to_inp

__all__ = ["EnginesBenchmark", "bench_engines", "compare_engines", "refinement", "weir_chain_case"]

START = pd.Timestamp("2020-01-01", tz="UTC")
SLOPE = 5e-4
CREST_ABOVE_BED = 1.8


def weir_chain_case(folder: str | Path, *, points: int = 400, weirs: int = 9, dx: float = 100.0, dt: float = 60.0,
                    days: float = 7.0, steady: bool = False, base: float = 2.0, peak: float = 6.0):
    """The weir chain (module docstring) as a case in ``folder``; about ``points`` calculation points at ``dx``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    length = points * 100.0  # the network is the same for every dx
    end = START + pd.Timedelta(days=days)
    times = pd.date_range(START - pd.Timedelta("3D"), end, freq="h")
    hours = (times - START).total_seconds().to_numpy() / 3600.0
    flow = np.full(hours.size, base) if steady else base + (peak - base) * np.exp(-(((hours - 48.0) / 12.0) ** 2))
    pd.DataFrame({"time": times.strftime("%Y-%m-%dT%H:%M:%SZ"), "Q": flow}).to_csv(folder / "inflow.csv", index=False)
    spacing = length / (weirs + 1)
    weir_list = [{"id": f"W{i + 1}", "branch": "C", "chainage": spacing * (i + 1),
                  "crest_level": SLOPE * (length - spacing * (i + 1)) + CREST_ABOVE_BED, "crest_width": 4.0}
                 for i in range(weirs)]
    spec = {
        "case": {"name": "weir-chain", "start": START.isoformat(), "end": end.isoformat(),
                 "description": f"{weirs} free weirs on a {length / 1000:g} km channel"},
        "engine": {"dt": dt, "output_interval": 3600.0},
        "initial": {"depth": 1.0, "spinup": 48.0},
        "friction": {"type": "strickler", "value": 30.0},
        "profiles": [{"id": "trap", "type": "trapezoidal", "bottom_width": 5.0, "side_slope": 1.5, "height": 4.0}],
        "nodes": [{"id": "up", "x": 0.0, "y": 0.0}, {"id": "down", "x": length, "y": 0.0}],
        "branches": [{"id": "C", "from_node": "up", "to_node": "down", "length": length, "dx": dx,
                      "cross_sections": [{"chainage": 0.0, "profile": "trap", "bed_level": SLOPE * length},
                                         {"chainage": length, "profile": "trap", "bed_level": 0.0}]}],
        "weirs": weir_list,
        "boundaries": [{"id": "Qin", "node": "up", "type": "discharge",
                        "series": {"file": "inflow.csv", "column": "Q"}},
                       {"id": "hout", "node": "down", "type": "level", "value": 0.8}],
        "stations": [{"id": f"S{i + 1}", "structure": f"W{i + 1}", "quantities": ["h_up", "h_down", "Q"]}
                     for i in range(weirs)],
    }
    return case_from_dict(spec, folder)


@dataclass(frozen=True)
class EnginePair:
    """Station series of both engines over one run and their wall times (s)."""

    embedded: pd.DataFrame
    swmm: pd.DataFrame
    embedded_wall_s: list[float]
    swmm_wall_s: list[float]
    points: int
    weirs: int

    def level_difference(self, since: pd.Timestamp | None = None) -> float:
        """Largest |embedded − SWMM| over the level series (m), from ``since`` on."""
        cols = [c for c in self.embedded.columns if not c.endswith(".Q")]
        a, b = self.embedded[cols], self.swmm[cols]
        if since is not None:
            a, b = a.loc[since:], b.loc[since:]
        return float((a - b).abs().to_numpy().max())


def compare_engines(case, *, swmm_dx: float = 100.0, routing_step: float = 10.0, variable_step: float = 0.75,
                    repeats: int = 1, folder: str | Path | None = None) -> EnginePair:
    """Run ``case`` on the embedded engine and on SWMM (converted with ``swmm_dx`` m conduits) ``repeats`` times."""
    from rivercal.models.swmm.model import SwmmModel

    model = EmbeddedModel(case)
    model.simulate({}, end=case.start + pd.Timedelta("1h"))  # compile (or load the cache) outside the timing
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        export = case_to_inp(case, model.forcing, dx=swmm_dx, routing_step=routing_step, variable_step=variable_step)
        inp = Path(tmp) / "chain.inp"
        inp.write_text(export.text, encoding="utf-8")
        swmm = SwmmModel(inp, export.stations, name="weir-chain", start=case.start, end=case.end,
                         spinup=case.spec.initial.spinup, runs_dir=tmp)
        emb_wall, swmm_wall = [], []
        for _ in range(repeats):  # interleaved, so that both see the same machine load
            t0 = time.perf_counter()
            emb, _ = model.simulate({})
            emb_wall.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            sw, _ = swmm.simulate({})
            swmm_wall.append(time.perf_counter() - t0)
    return EnginePair(embedded=emb.series, swmm=sw.series[emb.series.columns], embedded_wall_s=emb_wall,
                      swmm_wall_s=swmm_wall, points=model.compiled.n_hpoints, weirs=len(case.network.weirs))


@dataclass(frozen=True)
class EnginesBenchmark:
    """Result of :func:`bench_engines` (times in s, level difference in m)."""

    points: int
    weirs: int
    embedded_wall_s: float
    swmm_wall_s: float
    ratio: float
    max_level_diff_m: float

    def to_dict(self) -> dict:
        """Plain-dict form for JSON."""
        return asdict(self)


def bench_engines(points: int = 400, weirs: int = 9, days: float = 7.0, repeats: int = 5) -> EnginesBenchmark:
    """One simulated week of the weir chain on both engines, medians of ``repeats`` interleaved runs.

    The embedded engine runs with Δt = 60 s; SWMM with a 10 s routing step and variable steps (safety
    factor 0.75), 100 m conduits. ``max_level_diff_m`` is the largest level difference at the stations
    over the week of the flood wave, after the spin-up.
    """
    with tempfile.TemporaryDirectory() as tmp:
        case = weir_chain_case(tmp, points=points, weirs=weirs, days=days)
        pair = compare_engines(case, repeats=repeats, folder=tmp)
    emb, sw = statistics.median(pair.embedded_wall_s), statistics.median(pair.swmm_wall_s)
    return EnginesBenchmark(points=pair.points, weirs=pair.weirs, embedded_wall_s=round(emb, 4),
                            swmm_wall_s=round(sw, 3), ratio=round(sw / emb, 1),
                            max_level_diff_m=round(pair.level_difference(), 4))


#: Resolutions of :func:`refinement`: (Δx m, embedded Δt s, SWMM routing step s), coarse to fine.
LEVELS = ((400.0, 240.0, 40.0), (200.0, 120.0, 20.0), (100.0, 60.0, 10.0), (50.0, 30.0, 5.0))


def refinement(folder: str | Path, *, points: int = 100, weirs: int = 3, days: float = 4.0,
               levels: tuple[tuple[float, float, float], ...] = LEVELS) -> list[dict]:
    """The flood wave on both engines at each resolution of ``levels`` (fixed SWMM steps).

    Returns one row per resolution: Δx, both time steps, the largest level difference between the
    engines at the stations (m) and, for every resolution but the finest, each engine's largest level
    change to its own finest run (m): how far each is from convergence.
    """
    pairs = []
    for k, (dx, dt, step) in enumerate(levels):
        case = weir_chain_case(Path(folder) / f"level{k}", points=points, weirs=weirs, dx=dx, dt=dt, days=days)
        pairs.append(compare_engines(case, swmm_dx=dx, routing_step=step, variable_step=0.0, folder=folder))
    cols = [c for c in pairs[-1].embedded.columns if not c.endswith(".Q")]
    rows = []
    for (dx, dt, step), pair in zip(levels, pairs, strict=True):
        row = {"dx_m": dx, "embedded_dt_s": dt, "swmm_step_s": step,
               "embedded_vs_swmm_m": round(pair.level_difference(), 5),
               "embedded_wall_s": round(pair.embedded_wall_s[0], 3), "swmm_wall_s": round(pair.swmm_wall_s[0], 3)}
        if pair is not pairs[-1]:
            for name in ("embedded", "swmm"):
                change = getattr(pair, name)[cols] - getattr(pairs[-1], name)[cols]
                row[f"{name}_vs_finest_m"] = round(float(change.abs().to_numpy().max()), 5)
        rows.append(row)
    return rows
