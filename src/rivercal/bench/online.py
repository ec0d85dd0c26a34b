"""On-line service benchmarks: the wall time of one warm-started cycle and of a whole replay.

``rivercal bench online --mode parameters|both --json`` replays the PI-Fg scenario of thesis §5-2-1
(global friction 16 → 25 m^(1/3)/s on 2010-11-01) on the dommel case from an issue time after the change
has left the window, so that every cycle after the first is a warm start from the previous estimate with a
hot-started engine state: the steady regime of a service in operation. The first cycle (cold: DSS start,
JIT load, spin-up; with ``both`` also the cold ensemble) is reported apart. ``--mode parameters`` runs the
daily parameter cycle alone; ``--mode both`` (the service's default on dommel) adds the hourly ensemble
analyses of ``--members`` members and the ensemble forecast (:mod:`rivercal.online.assimilation`).
``--replay`` adds the four-week daily replay of ``make demo`` (2010-10-18 … 2010-11-15: truth, ingestion
and every cycle, no report), timed as a whole.

Times are wall-clock seconds of the machine it runs on: ``cycle_wall_s_*`` the cycle's computation as the service
stores it (``CycleOutcome.wall_s``), ``*_total_wall_s*`` also its commit
and the run metrics stored with it; beside them the processor time of the benchmark's process per cycle (its
threads included; worker processes of a calibration not). Report medians.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import pandas as pd

from rivercal.model import load_model
from rivercal.online.assimilation import AssimilationConfig
from rivercal.online.service import CycleOutcome, OnlineConfig, OnlineService
from rivercal.store import Store
from rivercal.twin.practical import practical_truth

__all__ = ["OnlineBenchmark", "bench_online"]


@dataclass(frozen=True)
class OnlineBenchmark:
    """Result of :func:`bench_online` (times in s, parameter values in their units)."""

    case: str
    scenario: str
    mode: str
    members: int | None
    parameters: list[str]
    window: str
    warmup: str
    workers: int | None
    first_issue: str
    cycles_timed: int
    cycle_wall_s_median: float
    cycle_wall_s_min: float
    cycle_wall_s_max: float
    cycle_model_runs_median: float
    cycle_cpu_s_median: float
    cycle_total_wall_s_median: float
    first_cycle_wall_s: float
    first_cycle_cpu_s: float
    first_cycle_total_wall_s: float
    cycle_wall_s_all: list
    final_estimates: dict
    replay_from: str | None
    replay_to: str | None
    replay_cycles: int | None
    replay_wall_s_median: float | None
    replay_wall_s_all: list | None

    def to_dict(self) -> dict:
        """Plain-dict form for JSON."""
        return asdict(self)


def _service(model, folder: Path, scenario: str, first: pd.Timestamp, last: pd.Timestamp,
             config: OnlineConfig, assimilation: AssimilationConfig | None = None) -> tuple[Store, OnlineService]:
    store = Store(folder / "bench.sqlite")
    service = OnlineService(model, store, scenario, config, first, meta={"scenario": scenario},
                            assimilation=assimilation)
    truth = practical_truth(model, scenario, *service.data_period(last), series=service.series)
    store.ingest(truth.observations, source=f"twin:{scenario}")
    return store, service


def bench_online(case: str = "dommel", scenario: str = "PI-Fg", *, first_issue: str = "2010-11-09",
                 cycles: int = 5, workers: int | None = None, replay: bool = False,
                 replay_from: str = "2010-10-18", replay_to: str = "2010-11-15",
                 replay_repeats: int = 3, mode: str = "parameters", members: int = 64) -> OnlineBenchmark:
    """Time warm-started cycles of the on-line service (and optionally whole replays).

    Parameters
    ----------
    case
        Case folder or packaged case name.
    scenario
        Practical scenario of thesis ch. 5 that makes the observations.
    first_issue
        Issue time (UTC) of the first, untimed cycle.
    cycles
        Timed warm-started cycles after the first (the median is reported).
    workers
        Worker processes per calibration (None: all cores).
    replay
        Also time whole replays ``replay_from`` .. ``replay_to`` (daily cycles), ``replay_repeats`` times.
    mode
        ``parameters`` (the daily parameter cycle alone) or ``both`` (with hourly ensemble analyses).
    members
        Ensemble members of ``both``.
    """
    if mode not in ("parameters", "both"):
        raise ValueError(f"the benchmark's mode must be parameters or both, got {mode!r}")
    model = load_model(case)
    config = OnlineConfig(workers=workers)
    assimilation = AssimilationConfig(mode="both", members=members) if mode == "both" else None
    first = pd.Timestamp(first_issue, tz="UTC")
    last = first + cycles * pd.Timedelta(config.period)
    cpu: list[float] = []
    total: list[float] = []
    mark = [time.process_time(), time.perf_counter()]

    def _tick(_: CycleOutcome) -> None:  # from one cycle's end to the next's: its commit and run metrics included
        now, wall = time.process_time(), time.perf_counter()
        cpu.append(now - mark[0])
        total.append(wall - mark[1])
        mark[:] = [now, wall]

    with tempfile.TemporaryDirectory(prefix="rivercal-bench-") as tmp:
        store, service = _service(model, Path(tmp), scenario, first, last, config, assimilation)
        with store:
            mark[:] = [time.process_time(), time.perf_counter()]
            try:
                outcomes = service.replay(last, progress=_tick)
            finally:
                service.close()
    walls = [o.wall_s for o in outcomes[1:]]
    runs = [o.model_runs for o in outcomes[1:]]
    replay_walls: list[float] = []
    n_replay = None
    if replay:
        r_first, r_last = pd.Timestamp(replay_from, tz="UTC"), pd.Timestamp(replay_to, tz="UTC")
        for _ in range(replay_repeats):
            with tempfile.TemporaryDirectory(prefix="rivercal-bench-") as tmp:
                t0 = time.perf_counter()
                store, service = _service(model, Path(tmp), scenario, r_first, r_last, config, assimilation)
                with store:
                    try:
                        n_replay = len(service.replay(r_last))
                    finally:
                        service.close()
                replay_walls.append(time.perf_counter() - t0)
    return OnlineBenchmark(
        case=model.name, scenario=scenario, mode=mode, members=members if mode == "both" else None,
        parameters=list(config.parameters), window=config.window,
        warmup=config.warmup, workers=workers, first_issue=first.isoformat(), cycles_timed=len(walls),
        cycle_wall_s_median=statistics.median(walls), cycle_wall_s_min=min(walls), cycle_wall_s_max=max(walls),
        cycle_model_runs_median=statistics.median(runs), cycle_cpu_s_median=statistics.median(cpu[1:]),
        cycle_total_wall_s_median=statistics.median(total[1:]), first_cycle_wall_s=outcomes[0].wall_s,
        first_cycle_cpu_s=cpu[0], first_cycle_total_wall_s=total[0],
        cycle_wall_s_all=[round(w, 3) for w in walls],
        final_estimates={k: round(v, 6) + 0.0 for k, v in outcomes[-1].accepted.items()},
        replay_from=replay_from if replay else None, replay_to=replay_to if replay else None,
        replay_cycles=n_replay, replay_wall_s_median=statistics.median(replay_walls) if replay_walls else None,
        replay_wall_s_all=[round(w, 2) for w in replay_walls] if replay_walls else None,
    )
