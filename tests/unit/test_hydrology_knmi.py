"""KNMI daily station files: units, trace codes, missing values, format errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rivercal.cases
from rivercal.errors import CaseError
from rivercal.hydrology.knmi import TRACE_VALUE, MeteoFormatError, read_knmi_daily

EINDHOVEN = Path(rivercal.cases.__file__).parent / "dommel" / "meteo" / "etmgeg_370_20100901-20101201.txt"

PRECIP_NETWORK = """\
THESE DATA CAN BE USED FREELY PROVIDED THAT THE FOLLOWING SOURCE IS ACKNOWLEDGED:
ROYAL NETHERLANDS METEOROLOGICAL INSTITUTE

RD       = daily precipitation amount in 0.1 mm over the period 08.00 preceding day - 08.00 UTC present day
5 spaces represents a missing value

STN,YYYYMMDD,   RD,   SX,
831,20101111,  122,     ,
831,20101112,     ,     ,
831,20101113,  313,  998,
"""


@pytest.fixture(scope="module")
def eindhoven() -> pd.DataFrame:
    return read_knmi_daily(EINDHOVEN)


def test_packaged_eindhoven_file_in_physical_units(eindhoven: pd.DataFrame) -> None:
    d = eindhoven
    assert len(d) == 92
    assert d.index[0] == pd.Timestamp("2010-09-01", tz="UTC")
    assert d.index[-1] == pd.Timestamp("2010-12-01", tz="UTC")
    assert (d["STN"] == 370).all()
    assert d.loc["2010-11-13", "RH"].item() == pytest.approx(24.4)
    assert d.loc["2010-11-13", "RHX"].item() == pytest.approx(2.8)
    assert d.loc["2010-11-13", "RHXH"].item() == 3
    assert d.loc["2010-11-13", "DR"].item() == pytest.approx(19.1)
    assert d.loc["2010-10-12", "TG"].item() == pytest.approx(6.9)
    assert d.loc["2010-10-12", "T10N"].item() == pytest.approx(-0.9)  # -9 is an ordinary value, not a code
    assert str(d["RHXH"].dtype) == "Int64"
    assert d.attrs["units"]["RH"] == "mm" and d.attrs["units"]["DR"] == "h" and d.attrs["units"]["RHXH"] == "hour"


def test_trace_code_becomes_documented_value(eindhoven: pd.DataFrame) -> None:
    d = eindhoven
    trace_days = d.attrs["trace"]["RH"]
    assert trace_days == ["2010-09-02", "2010-09-18", "2010-09-20", "2010-10-03", "2010-10-25",
                          "2010-11-26", "2010-11-27"]
    assert (d.loc[trace_days, "RH"] == TRACE_VALUE).all()
    assert d["RH"].sum() == pytest.approx(241.5 + 7 * TRACE_VALUE)
    assert d["EV24"].sum() == pytest.approx(90.1)
    assert d.loc["2010-11-08":"2010-11-15", "RH"].sum() == pytest.approx(73.4)
    zero = read_knmi_daily(EINDHOVEN, trace_value=0.0)
    assert zero["RH"].sum() == pytest.approx(241.5)
    with pytest.raises(ValueError, match="trace_value"):
        read_knmi_daily(EINDHOVEN, trace_value=0.1)


def test_missing_fields_are_nan_and_counted(eindhoven: pd.DataFrame) -> None:
    d = eindhoven
    assert np.isnan(d.loc["2010-10-03", "DDVEC"].item())
    assert d.attrs["missing"]["DDVEC"] == 1
    assert d.attrs["missing"]["NG"] == 4
    assert int(d["VVNH"].isna().sum()) == d.attrs["missing"]["VVNH"] == 8
    for col in ("RH", "RHX", "RHXH", "DR", "EV24"):
        assert col not in d.attrs["missing"]


def test_precipitation_network_format(tmp_path: Path) -> None:
    path = tmp_path / "neerslaggeg_TEST_831.txt"
    path.write_text(PRECIP_NETWORK)
    d = read_knmi_daily(path)
    assert list(d.columns) == ["STN", "RD", "SX"]
    assert d["RD"].iloc[0] == pytest.approx(12.2)
    assert np.isnan(d["RD"].iloc[1])
    assert d.attrs["missing"] == {"RD": 1, "SX": 2}


def _write(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "etmgeg.txt"
    path.write_text("BRON: KNMI\n\n# STN,YYYYMMDD,   RH, RHXH\n" + body)
    return path


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ("  370,20101101,   12,    3\n  370,20101102,   12\n", r"line 5.*expected 4 comma-separated fields, found 3"),
        ("  370,20101101,   1x,    3\n", r"line 4, column RH.*'1x' is not an integer"),
        ("  370,20101301,   12,    3\n", r"line 4, column YYYYMMDD.*not a valid date"),
        ("  370,20101102,   12,    3\n  370,20101101,   12,    3\n", r"line 5.*runs backwards"),
        ("  370,20101101,   12,    3\n  371,20101102,   12,    3\n", r"several stations"),
        ("", r"no data rows"),
    ],
)
def test_format_errors_name_file_line_and_column(tmp_path: Path, body: str, match: str) -> None:
    path = _write(tmp_path, body)
    with pytest.raises(MeteoFormatError, match=match) as info:
        read_knmi_daily(path)
    assert isinstance(info.value, CaseError)
    assert str(path) in str(info.value)


def test_no_header_and_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "x.txt"
    path.write_text("just text\n1,2,3\n")
    with pytest.raises(MeteoFormatError, match="STN,YYYYMMDD"):
        read_knmi_daily(path)
    with pytest.raises(FileNotFoundError):
        read_knmi_daily(tmp_path / "absent.txt")


def test_station_selection(tmp_path: Path) -> None:
    path = _write(tmp_path, "  370,20101101,   12,    3\n  371,20101101,   20,    4\n")
    d = read_knmi_daily(path, station=371)
    assert d["RH"].tolist() == [2.0]
    with pytest.raises(MeteoFormatError, match="station 999"):
        read_knmi_daily(path, station=999)
