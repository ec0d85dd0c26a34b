"""The on-line service at each realism level: every practical scenario × ideal, noisy, realistic × what it updates.

``rivercal bench realism --json`` replays the four weeks of ``make demo`` (cycles issued daily 2010-10-18 …
2010-11-15, the change on 2010-11-01) on the dommel case for each practical scenario of thesis §5-2, each
realism level of :mod:`rivercal.twin.realism` and each mode of the service (``--assimilate``: ``both``, the
default, and ``parameters``), with the service's defaults otherwise (FA and Wd, Huber cost, the transition
estimator, do no harm, 64 members), and reports the run metrics the service stored with its last cycle
(:mod:`rivercal.online.metrics`): ``forecast_mae_ratio``, ``time_to_correct_cycles``, ``jump_alerts``,
``fallbacks``, the 90 % band's coverage and the error by lead time, with the wall time. Every run is seeded
(``seed``), so the table is reproducible; the stores can be kept (``keep``) for the report.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from rivercal.model import load_model
from rivercal.models.contract import Model
from rivercal.observations import ScreenRule
from rivercal.online.assimilation import ASSIMILATE_MODES, AssimilationConfig
from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.store import Store
from rivercal.twin.practical import PRACTICAL_SCENARIOS, SCENARIOS, practical_truth
from rivercal.twin.realism import get_realism

__all__ = ["DEFINITIONS", "FIGURES", "bench_realism", "realism_run"]

#: The figures of each run that the table shows.
FIGURES = ("forecast_mae_ratio", "rivercal_mae_m", "dss_mae_m", "updated_mae_ratio", "time_to_correct_cycles",
           "time_to_settle_cycles", "time_to_correct_reason", "value_before_change", "estimated_change", "true_change",
           "jump_alerts", "fallbacks", "unscored_cycles")

#: What each figure of a row means (the JSON's ``definitions``).
DEFINITIONS = {
    "forecast_mae_ratio": "the DSS's mean absolute level error over rivercal's, level forecasts with lead times up to "
                          "24 h of the cycles issued after the change, rivercal being the forecast each cycle issued, "
                          "against the stored observations that were not flagged",
    "updated_mae_ratio": "the same for the updated parameters' forecasts, issued or not",
    "time_to_correct_cycles": "cycles issued after the change up to the first in which every changed parameter's "
                              "estimated change (its accepted value minus the value accepted by the last cycle before "
                              "the change) is within 5 % of the true change (1 cm for a crest shift); null when "
                              "nothing changes, the run does not estimate the changed parameter, or it never gets "
                              "there",
    "time_to_settle_cycles": "cycles issued after the change up to the first from which on every changed parameter "
                             "stays within the same tolerance of the run's last estimate",
    "value_before_change": "per changed parameter, the value accepted by the last cycle before the change",
    "estimated_change": "per changed parameter, the run's last accepted value minus value_before_change",
    "true_change": "per changed parameter, the truth's value after the change minus the value before",
    "jump_alerts": "number of jump alerts (probable interventions)",
    "fallbacks": "cycles that issued the DSS's forecast although updated forecasts had been scored",
    "unscored_cycles": "first cycles, with no updated forecast scored yet (they issue the DSS's)",
    "assimilate": "what the service updated: both (parameters daily, states hourly), parameters or states",
    "band_coverage_90": "with state updating: the share of the level observations (lead > 0, not flagged) inside "
                        "the ensemble forecasts' 90 % bands, over every cycle",
    "forecast_mae_by_lead": "mean absolute level error (m) of the updated (as issued) and the DSS's forecasts per "
                            "lead-time bucket, against the twin's noise-free truth",
}


def realism_run(model: Model, scenario: str, level: str, db: Path, *, first: str = "2010-10-18",
                last: str = "2010-11-15", seed: int = 0, config: OnlineConfig | None = None,
                assimilate: str = "both", members: int = 64) -> dict[str, Any]:
    """One replay of ``scenario`` under realism ``level`` into the store ``db``; its figures and wall time (s)."""
    from rivercal.online.metrics import mae_by_lead

    config = config or OnlineConfig()
    realism = get_realism(level)
    t0 = time.perf_counter()
    with Store(db) as store:
        meta: dict[str, Any] = {"scenario": scenario, "noise": "none", "seed": seed,
                                "truth": SCENARIOS[scenario].facts()}
        if not realism.ideal:
            meta["realism"] = realism.summary()
        assimilation = AssimilationConfig(mode=assimilate, members=members, seed=seed)
        service = OnlineService(model, store, f"{scenario}-{level}-{assimilate}", config,
                                pd.Timestamp(first, tz="UTC"), meta=meta, assimilation=assimilation)
        end = pd.Timestamp(last, tz="UTC")
        truth = practical_truth(model, scenario, *service.data_period(end), seed=seed, series=service.series,
                                realism=realism)
        store.ingest(truth.observations, source=f"twin:{scenario}", screen=ScreenRule())
        outcomes = service.replay(end)
        service.close()
        figures = store.metrics(service.run) or service.metrics()
        by_lead = mae_by_lead(store, service.run, service.series, truth.series)
    wall = time.perf_counter() - t0
    cover = figures.get("band_coverage_90")
    return {"scenario": scenario, "realism": level, "assimilate": assimilate, "seed": seed, "cycles": len(outcomes),
            **{k: figures.get(k) for k in FIGURES}, "band_coverage_90": cover["fraction"] if cover else None,
            "forecast_mae_by_lead": by_lead, "wall_s": round(wall, 1),
            "cycle_wall_s_median": float(pd.Series([o.wall_s for o in outcomes]).median()) if outcomes else None,
            "final_estimates": {k: round(v, 4) + 0.0 for k, v in outcomes[-1].accepted.items()} if outcomes else {}}


def bench_realism(case: str = "dommel", *, scenarios: Sequence[str] | None = None,
                  levels: Sequence[str] | None = None, seed: int = 0, workers: int | None = None,
                  keep: str | Path | None = None, modes: Sequence[str] = ("both", "parameters"),
                  members: int = 64) -> dict[str, Any]:
    """Every scenario × level × mode (default all scenarios; ideal, noisy, realistic): the rows of :func:`realism_run`.

    ``keep``: a folder for the stores (``<scenario>-<level>-<mode>.sqlite``); None: temporary ones.
    """
    for mode in modes:
        if mode not in ASSIMILATE_MODES:
            raise ValueError(f"unknown mode {mode!r}; choose among {', '.join(ASSIMILATE_MODES)}")
    scenarios = list(scenarios or PRACTICAL_SCENARIOS)
    levels = list(levels or ("ideal", "noisy", "realistic"))
    model = load_model(case)
    config = OnlineConfig(workers=workers)
    rows = []
    with tempfile.TemporaryDirectory(prefix="rivercal-realism-") as tmp:
        folder = Path(keep) if keep is not None else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for scenario in scenarios:
            for level in levels:
                for mode in modes:
                    db = folder / f"{scenario}-{level}-{mode}.sqlite"
                    for suffix in ("", "-wal", "-shm"):
                        Path(f"{db}{suffix}").unlink(missing_ok=True)
                    rows.append(realism_run(model, scenario, level, db, seed=seed, config=config, assimilate=mode,
                                            members=members))
    return {"case": model.name, "from": "2010-10-18", "to": "2010-11-15", "seed": seed, "workers": workers,
            "parameters": list(config.parameters), "loss": config.loss, "members": members,
            "definitions": DEFINITIONS, "rows": rows}
