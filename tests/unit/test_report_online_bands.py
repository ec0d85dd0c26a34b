"""The on-line report's band figure and the band coverage, from a store filled with known bands and observations."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import numpy as np
import pandas as pd
import pytest

from rivercal.observations import ObservationSet
from rivercal.online.metrics import band_coverage
from rivercal.report.html import Page
from rivercal.report.online_bands import band_blocks, band_figure
from rivercal.store import BandRecord, CycleRecord, Schedule, Store

SCHEDULE = Schedule("2010-11-01T00:00:00Z", period=pd.Timedelta(days=1), window=pd.Timedelta(days=2))
SERIES = ["0028.h_up", "0029.h_down", "0029.Q"]


@pytest.fixture
def store(tmp_path: Path):
    with Store(tmp_path / "s.db") as s:
        run = s.ensure_run("r", "dommel", {"sources": None})
        obs = {}
        for k in range(2):
            spec = s.begin_cycle(run.id, s.next_cycle(run.id, SCHEDULE))
            times = pd.date_range(spec.issue_time, periods=25, freq="h")
            hour = np.arange(25) + 24 * k   # hours since the first issue time: the cycles agree where they overlap
            mean = pd.DataFrame({c: 7.0 + 0.1 * np.sin(hour / 5.0) for c in SERIES}, index=times)
            s.commit_cycle(run.id, CycleRecord(k, spec.window_start, spec.window_end, spec.issue_time,
                                               forecasts={"updated": mean, "dss": mean + 0.03},
                                               bands=BandRecord(mean - 0.05, mean + 0.05)))
            # observations: inside the band except every 4th hour (0.08 above the mean, outside)
            off = np.where(hour % 4 == 3, 0.08, 0.02)
            for c in SERIES:
                obs.update({(c, t): v for t, v in zip(times, mean[c].to_numpy() + off, strict=True)})
        frame = pd.Series(obs).unstack(0)
        s.ingest(ObservationSet.from_frame(frame), "telemetry")
        yield s, run


def test_the_coverage_counts_the_level_observations_inside_the_stored_bands(store) -> None:
    s, run = store
    cover = band_coverage(s, run)
    # leads 1..24 of 2 cycles and 2 level series (the discharge is left out); a time two cycles forecast counts twice
    hours = np.arange(1, 25)
    expected_inside = (hours % 4 != 3).sum() * 2 * 2
    assert cover["n"] == 24 * 2 * 2
    assert cover["fraction"] == pytest.approx(expected_inside / cover["n"])
    assert cover["probability"] == 0.9


def test_the_band_figure_draws_the_last_cycles_band(store, tmp_path: Path) -> None:
    s, run = store
    path = band_figure(s, run, tmp_path / "band.png")
    image = matplotlib.image.imread(path)[..., :3]
    band = np.array([0x2B, 0x6C, 0xB0]) / 255 * 0.22 + 0.78   # the band's colour at 22 % over white
    assert (np.abs(image - band).max(axis=2) < 0.03).sum() > 2000   # a filled band, not a line
    files: dict[str, str] = {}
    blocks = band_blocks(s, run, tmp_path, files)
    page = Page("r")
    page.section("bands", *blocks)
    page.write(tmp_path / "index.html")
    html = (tmp_path / "index.html").read_text()
    assert "75% of 96 level observations fell inside the 90% band" in html and files["band_figure"]


def test_a_run_without_bands_gets_no_band_section(tmp_path: Path) -> None:
    with Store(tmp_path / "s.db") as s:
        run = s.ensure_run("r", "dommel", {})
        assert band_figure(s, run, tmp_path / "band.png") is None
        assert band_blocks(s, run, tmp_path, {}) == []
        assert band_coverage(s, run) == {"n": 0, "fraction": None}
