"""Hupsel Brook hourly data (read from outside the repository) and a default-parameter model run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.hydrology.hupsel import ENV_VAR, hupsel_path, read_hupsel
from rivercal.hydrology.knmi import MeteoFormatError
from rivercal.hydrology.metrics import kling_gupta, nash_sutcliffe
from rivercal.hydrology.runoff import WalrusParameters, simulate


@pytest.fixture(scope="module")
def hupsel(hupsel_file: Path) -> pd.DataFrame:
    return read_hupsel(hupsel_file)


def test_hupsel_record(hupsel: pd.DataFrame) -> None:
    h = hupsel
    assert len(h) == 23616
    assert h.index[0] == pd.Timestamp("2011-01-01 00:00", tz="UTC")
    assert h.index[-1] == pd.Timestamp("2013-09-10 23:00", tz="UTC")
    assert (h.index[1:] - h.index[:-1] == pd.Timedelta(hours=1)).all()
    assert h.attrs["missing"] == {"Q": 105}
    assert h["P"].sum() == pytest.approx(1922.3, abs=0.05)
    assert h["ETpot"].sum() == pytest.approx(1676.8, abs=0.05)


def test_default_model_over_the_whole_hupsel_record(hupsel: pd.DataFrame) -> None:
    h = hupsel
    result = simulate(WalrusParameters(), h["P"], h["ETpot"], initial=float(h["Q"].iloc[0]))
    q = result.q
    assert np.isfinite(q).all() and (q >= 0.0).all()
    assert abs(result.water_balance()["residual"]) < 1e-9
    nse = nash_sutcliffe(h["Q"], q)
    kge = kling_gupta(h["Q"], q)
    # a priori parameters, not calibrated: a floor that catches a broken model, not a target
    assert nse > 0.5, nse
    assert kge > 0.4, kge


def test_missing_file_names_the_environment_variable(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "absent.dat"))
    with pytest.raises(FileNotFoundError, match=ENV_VAR):
        hupsel_path()
    with pytest.raises(FileNotFoundError, match=ENV_VAR):
        read_hupsel()


def test_reader_on_a_small_file(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    path = tmp_path / "PEQ.dat"
    path.write_text('"date" "P" "ETpot" "Q"\n2011010100 0 0 0.042\n2011010101 1.5 0 NA\n2011010102 0 0.1 0.05\n')
    monkeypatch.setenv(ENV_VAR, str(path))
    h = read_hupsel()
    assert h.attrs["missing"] == {"Q": 1}
    assert np.isnan(h["Q"].iloc[1]) and h["P"].iloc[1] == 1.5
    assert h.index[1] == pd.Timestamp("2011-01-01 01:00", tz="UTC")
    path.write_text('"date" "P" "ETpot" "Q"\n2011010100 0 x 0.042\n')
    with pytest.raises(MeteoFormatError, match=r"line 2, column ETpot"):
        read_hupsel(path)
    path.write_text('"date" "P" "Q"\n')
    with pytest.raises(MeteoFormatError, match="header"):
        read_hupsel(path)


def test_metrics() -> None:
    obs = np.array([1.0, 2.0, 3.0, np.nan, 5.0])
    assert nash_sutcliffe(obs, obs) == 1.0
    assert kling_gupta(obs, obs) == pytest.approx(1.0)
    assert nash_sutcliffe(obs, np.full(5, np.nanmean(obs))) == pytest.approx(0.0)
    assert kling_gupta(obs, 2.0 * obs) < 0.5
    with pytest.raises(ValueError, match="length"):
        nash_sutcliffe(obs, obs[:3])
