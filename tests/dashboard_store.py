"""A store of synthetic daily cycles written through the store API (dashboard tests and benchmark).

Every number is a known function of the cycle index, so a test can say what a page must show. The
series are those of the packaged case ``dommel`` (so the map can draw its network, and the pages can say
what its parameters set and what the DSS's values are: FA 16 m^(1/3)/s, Wd 0 m).

rivercal's forecasts lie above the observations at the stations of :data:`HIGH` and below them at the others
(a known sign per station for the map's colours); the DSS's lie above them everywhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.observations import ObservationSet
from rivercal.online.metrics import score_forecasts
from rivercal.store import AlertRecord, CycleRecord, EstimateRecord, Store, TransitionRecord

SERIES = ["0028.h_up", "0028.h_down", "0040.h_up", "0040.h_down", "0029.h_up", "0029.h_down", "0029.Q", "0030.h_up",
          "0030.h_down", "0031.h_up", "0031.h_down"]
FIRST = pd.Timestamp("2010-01-08T00:00Z")
#: Stations whose rivercal forecasts are too high (the others' are too low).
HIGH = ("0028", "0040", "0029")
#: The change every cycle from :data:`CHANGE_FOUND` on carries until the window has passed it.
CHANGE_FOUND, CHANGE_LAST = 10, 16
CHANGE_TIME = FIRST + pd.Timedelta(days=9, hours=6)
CONFIG = {"parameters": ["FA", "Wd"], "window": "7D", "period": "1D", "horizon": "48h", "algorithm": "dud",
          "first_issue": FIRST.isoformat(), "dss": {}}


def observed(series: str, times: pd.DatetimeIndex) -> np.ndarray:
    """The synthetic truth: a base level per series plus a slow daily wave, m (or m³/s)."""
    base = 2.0 + SERIES.index(series) * 0.7
    hours = (times - FIRST).total_seconds().to_numpy() / 3600.0
    return base + 0.2 * np.sin(2 * np.pi * hours / 24.0) + 0.001 * hours / 24.0


def record(k: int) -> CycleRecord:
    """Cycle ``k``: FA 16 → 25 at cycle 10, a held Wd every 7th cycle, a jump alert at cycle 10 and the transition
    it found carried to cycle 16, forecasts; every 4th cycle from the fourth on issues the DSS's forecast (a
    fallback), the others the updated one."""
    t0 = FIRST + pd.Timedelta(days=k)
    fa = 16.0 + (9.0 if k >= 10 else 0.0) + 0.01 * k
    held = k % 7 == 3
    reason = "this window cannot see Wd (identifiability index 0.10 < 0.5)" if held else None
    estimates = (EstimateRecord("FA", fa, "m^(1/3)/s", std=0.1 + 0.001 * k),
                 EstimateRecord("Wd", 0.01 * (k % 5), "m", std=0.002, accepted=not held, reason=reason))
    alerts = (AlertRecord("jump", f"FA changed from 16.1 to {fa:.4g} m^(1/3)/s: a probable intervention (mowing)",
                          parameter="FA", magnitude=45.0),) if k == 10 else ()
    times = pd.date_range(t0, t0 + pd.Timedelta("48h"), freq="h")
    truth = pd.DataFrame({s: observed(s, times) for s in SERIES}, index=times)
    lead = np.arange(len(times))[:, None] / 48.0
    sign = np.array([1.0 if s.partition(".")[0] in HIGH else -1.0 for s in SERIES])
    forecasts = {"updated": truth + sign * (0.01 + 0.02 * lead), "dss": truth + 0.05 + 0.10 * lead}
    moves = ()
    if CHANGE_FOUND <= k <= CHANGE_LAST:
        moves = (TransitionRecord(parameter="FA", time=CHANGE_TIME, before=16.0, after=fa, unit="m^(1/3)/s",
                                  found_cycle=CHANGE_FOUND, cost_single=100.0, cost_transition=40.0, p_value=1e-6),)
    return CycleRecord(k, t0 - pd.Timedelta("7D"), t0, t0, algorithm="dud", model_runs=8 + k % 4,
                       wall_time_s=0.5 + 0.01 * k, cost_before=100.0 / (k + 1), cost_after=1.0 / (k + 1),
                       message="converged", estimates=estimates, alerts=alerts, forecasts=forecasts, transitions=moves,
                       issued="dss" if k % 4 == 3 else "updated", issued_reason=issued_reason(k))


def issued_reason(k: int) -> str:
    """Why cycle ``k`` issued its forecast (see :func:`record`)."""
    if k % 4 == 3:
        return f"fallback to the DSS's parameters: the updated ones forecast worse recently (cycle {k})"
    return f"the updated parameters' forecast (cycle {k})"


def build_store(path: Path, n_cycles: int, *, run: str = "dash", case: str = "dommel") -> Path:
    """Write ``n_cycles`` daily cycles, hourly observations up to the last forecast, and the scores."""
    with Store(path, synchronous="NORMAL") as store:
        run_id = store.create_run(run, case, CONFIG)
        times = pd.date_range(FIRST - pd.Timedelta("8D"), FIRST + pd.Timedelta(days=n_cycles + 2), freq="h")
        frame = pd.DataFrame({s: observed(s, times) for s in SERIES}, index=times)
        store.ingest(ObservationSet.from_frame(frame), source="synthetic")
        for k in range(n_cycles):
            store.commit_cycle(run_id, record(k))
        _score(store, run_id)
    return path


def _score(store: Store, run: object, cycle: int | None = None) -> None:
    """Score the stored forecasts (of one cycle) against the stored observations, and store the scores."""
    fc = store.forecasts(run, cycle=cycle)
    observed = store.observation_table(sorted(fc["series"].unique()), fc["time"].min(), fc["time"].max())
    store.put_scores(run, score_forecasts(fc, observed))


def add_cycle(path: Path, run: str = "dash") -> int:
    """Commit the next cycle (as a running service would) and score it; returns its index."""
    with Store(path) as store:
        info = store.get_run(run)
        k = len(store.cycles(info))
        store.commit_cycle(info, record(k))
        _score(store, info, k)
    return k
