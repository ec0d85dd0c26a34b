"""One set of numbers: the terminal, the JSON, the report, the dashboard and the store give one figure per thing.

One short on-line run through the CLI (twin PI-Fg, two daily cycles after the change, a three-day window: the
replay :data:`tests.run_artefacts.PIFG_REPLAY`, run once per test run and also checked by
``tests/e2e/test_online_cli.py``) writes its store, its report and its JSON summary. The test reads the forecast
figures from all of them — the JSON, the terminal summary printed from it, the report's headline and its
Forecasts section, the dashboard's "Now" view and the metrics stored with the run — and requires the
same numbers and the same statement of which forecasts they cover. The stored figure itself is checked
against an independent recomputation from the store's forecasts and observations.
"""

from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.store import Store
from tests.run_artefacts import PIFG_RUN, pifg_replay

pytestmark = pytest.mark.slow

RUN = PIFG_RUN


class _Text(HTMLParser):
    def __init__(self):
        super().__init__()
        self.parts: list[str] = []

    def handle_data(self, data):
        self.parts.append(data)


@pytest.fixture(scope="module")
def done() -> tuple[Path, dict]:
    return pifg_replay()


def _cm(metres: float) -> str:
    return f"{metres * 100:.2f} cm"


def _served_now_page(db: Path) -> str:
    """The dashboard's "Now" page as its real server sends it (uvicorn on a free local port), as text."""
    import threading
    import time
    import urllib.request

    import uvicorn

    from rivercal.dashboard.app import create_app

    server = uvicorn.Server(uvicorn.Config(create_app(db), host="127.0.0.1", port=0, log_level="warning",
                                          access_log=False))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 30
        while not server.started and time.monotonic() < deadline:
            time.sleep(0.05)
        port = server.servers[0].sockets[0].getsockname()[1]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/?run={RUN}", timeout=30) as answer:
            page = answer.read().decode("utf-8")
    finally:
        server.should_exit = True
        thread.join(timeout=30)
    parser = _Text()
    parser.feed(page)
    return " ".join(" ".join(parser.parts).split())


def _terminal(summary: dict) -> str:
    from rivercal.cli.common import out_console
    from rivercal.cli.online import print_summary

    with out_console.capture() as captured:
        print_summary(summary)
    return " ".join(captured.get().split())


def test_every_surface_gives_the_stored_figures_and_says_what_they_cover(done) -> None:
    folder, summary = done
    from rivercal.dashboard.views import now_view

    with Store(folder / "run.sqlite", readonly=True) as store:
        run = store.get_run(RUN)
        stored = store.metrics(run)
        dashboard = " ".join(now_view(store, run)["figures"])
    # the JSON carries the stored metrics as they are
    for key in ("rivercal_mae_m", "dss_mae_m", "updated_mae_m", "forecast_values", "forecast_mae_ratio", "fallbacks",
                "unscored_cycles", "jump_alerts", "forecast_scope"):
        assert summary[key] == stored[key], key
    assert stored["forecast_values"] > 0
    scope = stored["forecast_scope"]
    assert (scope["first_cycle"], scope["last_cycle"]) == (0, 1)  # both cycles are issued after the change
    covers = f"issued by cycles 0–1 (the cycles issued after the change at {stored['change_time'][:16]}".replace(
        "T", " ")
    numbers = [f"rivercal as issued {_cm(stored['rivercal_mae_m'])}", f"the fixed DSS {_cm(stored['dss_mae_m'])}",
               f"n = {stored['forecast_values']} values", "lead times up to 24 h", covers]
    html = (folder / "report" / "index.html").read_text(encoding="utf-8")
    parser = _Text()
    parser.feed(html)
    report = " ".join(" ".join(parser.parts).split())
    terminal = _terminal(summary)
    served = _served_now_page(folder / "run.sqlite")
    for where, text in (("terminal", terminal), ("dashboard view", dashboard), ("dashboard page", served),
                        ("report", report)):
        for words in numbers:
            assert words in text, f"{where} lacks {words!r}"
    # the report says it twice, in its headline and in its Forecasts section, and no other MAE against the DSS
    assert report.count(f"rivercal as issued {_cm(stored['rivercal_mae_m'])}") == 2
    assert len(set(re.findall(r"rivercal as issued (\d+\.\d+) cm", report))) == 1
    assert f"Jump alerts: {stored['jump_alerts']}; fallbacks to the DSS's forecast: {stored['fallbacks']}" in terminal
    assert f"Jump alerts: {stored['jump_alerts']}; fallbacks to the DSS's forecast: {stored['fallbacks']}" in report
    # the run's end: the forecast the last cycle issued, in the terminal's words and the JSON's
    assert summary["final_state"][0].startswith("At the end of the run, cycle 1 (2010-11-10 00:00) issued")
    assert summary["final_state"][0] in terminal


def test_the_stored_figure_is_the_mean_error_of_the_issued_forecasts(done) -> None:
    """An independent recomputation: the issued forecast of each cycle, leads (0, 24] h, against the observations."""
    folder, _ = done
    with Store(folder / "run.sqlite", readonly=True) as store:
        run = store.get_run(RUN)
        stored = store.metrics(run)
        cycles = store.cycles(run).set_index("cycle")
        fc = store.forecasts(run)
        fc = fc[(fc["lead_h"] > 0) & (fc["lead_h"] <= 24) & fc["series"].str.contains(r"\.h(?:_up|_down)?$")]
        obs = store.observation_table(sorted(fc["series"].unique()), fc["time"].min(), fc["time"].max())
    pairs = fc.merge(obs[["series", "time", "value"]], on=["series", "time"], suffixes=("", "_obs"))
    pairs["err"] = (pairs["value"] - pairs["value_obs"]).abs()
    wide = pairs.pivot_table(index=["cycle", "series", "time"], columns="kind", values="err").dropna()
    issued = cycles["issued_forecast"].reindex(wide.index.get_level_values("cycle")).to_numpy()
    mine = np.where(issued == "dss", wide["dss"], wide["updated"])
    assert len(wide) == stored["forecast_values"]
    assert float(np.mean(mine)) == pytest.approx(stored["rivercal_mae_m"], rel=1e-9)
    assert float(wide["dss"].mean()) == pytest.approx(stored["dss_mae_m"], rel=1e-9)
    # the first cycle had nothing scored and issued the DSS's forecast: not a fallback
    assert cycles.loc[0, "issued_forecast"] == "dss" and stored["unscored_cycles"] >= 1
    assert isinstance(pd.Timestamp(stored["change_time"]), pd.Timestamp)
