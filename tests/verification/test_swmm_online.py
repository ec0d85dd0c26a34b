"""The on-line service on the SWMM case: seven daily cycles of scenario PI-Wg, hot-started from SWMM hotstarts.

Known truth: the nine adjustable crests drop 15 cm on 2010-11-01 (thesis §5-2-1), the friction stays.
Every cycle after the first starts SWMM from the hotstart file the previous cycle stored; the crest
shift Wd must follow the truth (0 before the change, -0.15 m once a cycle's runs lie after it), and the
roughness factor, which a day of low flow cannot see, is held by the identifiability gate.
"""

from __future__ import annotations

import pandas as pd
import pytest

from rivercal.models import FileState, load_model
from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.store import Store
from rivercal.twin.practical import practical_truth

pytestmark = pytest.mark.slow


def test_seven_daily_cycles_of_pi_wg_on_swmm_hot_started_from_hotstart_files(tmp_path) -> None:
    model = load_model("dommel-swmm")
    config = OnlineConfig(parameters=("FR", "Wd"), window="1D", warmup="12h", horizon="12h", workers=1,
                          deadline_s=None)
    with Store(tmp_path / "run.sqlite") as store:
        service = OnlineService(model, store, "PI-Wg", config, "2010-10-29")
        truth = practical_truth(model, "PI-Wg", *service.data_period("2010-11-04"), series=service.series)
        store.ingest(truth.observations, source="twin:PI-Wg")
        cycles = service.replay("2010-11-04")
        assert len(cycles) == 7 and all(c.status == "done" for c in cycles)
        assert [c.hot_start for c in cycles] == [False] + [True] * 6
        when, fmt, data = store.model_state(service.run, "updated")
        assert when == pd.Timestamp("2010-11-04", tz="UTC") - pd.Timedelta("36h") + pd.Timedelta("1D")
        assert fmt == model.state_format and isinstance(model.load_state(data, fmt), FileState)
        assert "hotstart.hsf" in model.load_state(data, fmt).files
        for c in cycles:
            # the runs of the cycle (warm-up and window) all lie after the change
            after = c.issue_time - pd.Timedelta("36h") >= pd.Timestamp("2010-11-01", tz="UTC")
            if c.issue_time <= pd.Timestamp("2010-11-01", tz="UTC"):
                assert abs(c.accepted["Wd"]) < 0.005, c
            elif after:
                assert c.accepted["Wd"] == pytest.approx(-0.15, abs=0.005), c
        # a day of low flow cannot see the roughness: the identifiability gate holds it (at 1 before the change)
        for c in cycles[1:4]:
            assert c.accepted["FR"] == 1.0 and "cannot see FR" in c.held["FR"]
        assert any(a.kind == "jump" and a.parameter == "Wd" for c in cycles for a in c.alerts)
