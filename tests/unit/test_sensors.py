"""Gauge files as delivered, read through sidecars: MATROOS/NOOS exports, loggers' CSV in local time, depths, flags.

The expected UTC times are worked out by hand (the Dutch clocks went back from 03:00 CEST to 02:00 CET at
01:00 UTC on 31 October 2021 and forward from 02:00 CET to 03:00 CEST at 01:00 UTC on 28 March 2021), and
checked against :mod:`zoneinfo` where that is the independent reference.
"""

from __future__ import annotations

import re
from datetime import datetime
from pathlib import Path
from zoneinfo import ZoneInfo

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import CaseError
from rivercal.io import read_observations, read_sidecar
from rivercal.io.sensors import SIDECAR_SCHEMA, parse_time_zone

NOOS = """#------------------------------------------------------
# Timeseries retrieved from the MATROOS series database
# Created at Mon Feb 26 16:12:08 CET 2018
#------------------------------------------------------
# Location    : bath
# Position    : (4.210261,51.400048)
# Source      : observed
# Unit        : waterlevel
# Analyse time:
# Timezone    : GMT
#------------------------------------------------------
201312050000   -0.23
201312050010   -0.12
201312050020   0.00
201312050030
201312050040   0.22
"""


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _sidecar(folder: Path, body: str, name: str = "gauge.toml") -> Path:
    return _write(folder, name, "[[series]]\n" + body)


def _error(path: Path) -> str:
    with pytest.raises(CaseError) as info:
        read_sidecar(path)
    return str(info.value)


# -- MATROOS / NOOS exports ---------------------------------------------------------------------------------


def test_a_matroos_export_is_read_with_its_header_time_zone_and_unit(tmp_path: Path) -> None:
    _write(tmp_path, "bath.txt", NOOS)
    side = _sidecar(tmp_path, 'id = "bath.h"\nfile = "bath.txt"\nformat = "matroos"\nlocation = "bath"\n')
    s = read_sidecar(side)["bath.h"]
    assert list(s.times) == list(pd.to_datetime(["2013-12-05 00:00", "2013-12-05 00:10", "2013-12-05 00:20",
                                                  "2013-12-05 00:40"]).tz_localize("UTC"))
    np.testing.assert_array_equal(s.values, [-0.23, -0.12, 0.0, 0.22])
    assert s.n_missing == 1  # the empty value at 00:30 is dropped, never read as 0
    assert s.source == "bath.txt" and s.sigma is None


def test_the_packaged_westerscheldt_exports_read_as_rijkswaterstaat_wrote_them() -> None:
    from importlib import resources

    folder = Path(str(resources.files("rivercal.cases") / "westerscheldt"))
    obs = read_observations(folder / "gauges.toml")
    assert obs.ids == ["vlissingen.h", "terneuzen.h", "hansweert.h", "bath.h"]
    bath = obs["bath.h"]
    # the file's own lines, read independently: 289 values every 10 minutes, 5 to 7 December 2013, GMT
    rows = [line.split() for line in (folder / "waterlevel_bath.txt").read_text().splitlines()
            if line.strip() and not line.startswith("#")]
    assert len(bath) == len(rows) == 289
    assert bath.times[0] == pd.Timestamp("2013-12-05T00:00Z") and bath.times[-1] == pd.Timestamp("2013-12-07T00:00Z")
    np.testing.assert_array_equal(bath.values, [float(v) for _, v in rows])
    assert bath.values.max() == 4.72  # the storm's high water at Bath, m NAP


def test_a_matroos_header_without_its_unit_line_is_refused_naming_file_and_line(tmp_path: Path) -> None:
    _write(tmp_path, "bath.txt", NOOS.replace("# Unit        : waterlevel\n", ""))
    msg = _error(_sidecar(tmp_path, 'id = "bath.h"\nfile = "bath.txt"\nformat = "noos"\n'))
    assert "bath.txt" in msg and "line 10:" in msg and "no 'Unit' line" in msg


def test_a_matroos_file_of_another_quantity_or_place_is_refused(tmp_path: Path) -> None:
    _write(tmp_path, "waves.txt", NOOS.replace("waterlevel", "wave_height"))
    msg = _error(_sidecar(tmp_path, 'id = "bath.h"\nfile = "waves.txt"\nformat = "noos"\n'))
    assert re.search(r"waves\.txt: line 8: Unit 'wave_height' is not a water level", msg), msg
    _write(tmp_path, "bath.txt", NOOS)
    msg = _error(_sidecar(tmp_path, 'id = "hansweert.h"\nfile = "bath.txt"\nformat = "noos"\nlocation = "hansweert"\n'))
    assert "bath.txt: line 5: the file is of location 'bath'" in msg


def test_a_sidecar_time_zone_that_contradicts_the_header_is_refused(tmp_path: Path) -> None:
    _write(tmp_path, "bath.txt", NOOS)
    side = _sidecar(tmp_path, 'id = "bath.h"\nfile = "bath.txt"\nformat = "noos"\ntime_zone = "CET"\n')
    msg = _error(side)
    assert msg.startswith(f"{side}: series[0].time_zone: line 5: time_zone 'CET' contradicts line 10 of"), msg


def test_a_header_time_zone_other_than_utc_shifts_the_times(tmp_path: Path) -> None:
    _write(tmp_path, "met.txt", NOOS.replace("Timezone    : GMT", "Timezone    : MET"))
    s = read_sidecar(_sidecar(tmp_path, 'id = "bath.h"\nfile = "met.txt"\nformat = "noos"\n'))["bath.h"]
    assert s.times[0] == pd.Timestamp("2013-12-04T23:00Z")  # 00:00 at UTC+1


# -- local clock time across the changes of summer time --------------------------------------------------------


AUTUMN_HOURLY = "time,h\n2021-10-31 00:00,1.0\n2021-10-31 01:00,1.1\n2021-10-31 02:00,1.2\n2021-10-31 02:00,1.3\n" \
                "2021-10-31 03:00,1.4\n"


def test_local_clock_time_across_the_end_of_summer_time_follows_the_clock(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", AUTUMN_HOURLY)
    side = _sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'
                              'time_zone = "Europe/Amsterdam"\n')
    s = read_sidecar(side)["P.h"]
    by_hand = ["2021-10-30T22:00Z", "2021-10-30T23:00Z", "2021-10-31T00:00Z", "2021-10-31T01:00Z",
               "2021-10-31T02:00Z"]  # 02:00 CEST, then 02:00 CET an hour later
    assert [t.isoformat() for t in s.times] == [pd.Timestamp(t).isoformat() for t in by_hand]
    np.testing.assert_array_equal(s.values, [1.0, 1.1, 1.2, 1.3, 1.4])


def test_ten_minute_local_times_step_back_at_the_end_of_summer_time_and_match_zoneinfo(tmp_path: Path) -> None:
    clock = [f"2021-10-31 0{h}:{m}0" for h in (1, 2) for m in range(6)] + [f"2021-10-31 02:{m}0" for m in range(6)] \
        + ["2021-10-31 03:00"]
    _write(tmp_path, "p.csv", "time,h\n" + "".join(f"{t},{k}\n" for k, t in enumerate(clock)))
    side = _sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'
                              'time_zone = "Europe/Amsterdam"\n')
    s = read_sidecar(side)["P.h"]
    zone = ZoneInfo("Europe/Amsterdam")
    expected = [datetime.fromisoformat(t).replace(tzinfo=zone, fold=1 if k >= 12 else 0) for k, t in enumerate(clock)]
    assert [t.to_pydatetime() for t in s.times] == [pd.Timestamp(e).tz_convert("UTC").to_pydatetime() for e in expected]
    assert (np.diff(s.times.asi8) == 600 * 10**9).all()  # evenly every 10 minutes in UTC


def test_local_time_read_with_a_fixed_offset_is_refused_at_the_repeated_hour(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", AUTUMN_HOURLY)
    msg = _error(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\ntime_zone = "CET"\n'))
    assert "p.csv: line 5: the time 2021-10-31 01:00:00 UTC appears twice (also on line 4)" in msg, msg
    assert "summer time ended" in msg and "Europe/Amsterdam" in msg


def test_a_clock_time_in_the_hour_skipped_in_spring_is_refused(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-03-28 01:30,1.0\n2021-03-28 02:30,1.1\n2021-03-28 03:30,1.2\n")
    msg = _error(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'
                                    'time_zone = "Europe/Amsterdam"\n'))
    assert "p.csv: line 3: 2021-03-28 02:30 does not exist in Europe/Amsterdam" in msg, msg
    assert "UTC+01:00" in msg


def test_a_single_reading_in_the_repeated_hour_is_ambiguous(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-10-31 01:40,1.0\n2021-10-31 02:25,1.1\n2021-10-31 03:10,1.2\n")
    msg = _error(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'
                                    'time_zone = "Europe/Amsterdam"\n'))
    assert "p.csv: line 3: 2021-10-31 02:25 is ambiguous in Europe/Amsterdam" in msg, msg


@pytest.mark.parametrize(("zone", "hours"), [("UTC", 0.0), ("GMT", 0.0), ("+01:00", 1.0), ("UTC+1", 1.0),
                                             ("GMT-03:30", -3.5), ("CEST", 2.0), ("MET", 1.0)])
def test_fixed_offsets_shift_naive_times_and_keep_written_offsets(tmp_path: Path, zone: str, hours: float) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-06-01T12:00,1.0\n2021-06-01T18:00+02:00,1.1\n")
    s = read_sidecar(_sidecar(tmp_path, f'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'
                                        f'time_zone = "{zone}"\n'))["P.h"]
    assert s.times[0] == pd.Timestamp("2021-06-01T12:00Z") - pd.Timedelta(hours=hours)
    assert s.times[1] == pd.Timestamp("2021-06-01T16:00Z")  # the stamp's own offset wins


def test_time_zones_are_parsed_or_refused_with_the_forms_accepted() -> None:
    assert parse_time_zone("Europe/Brussels").region == "Europe/Brussels"
    assert parse_time_zone("utc-0500").offset_h == -5.0
    with pytest.raises(ValueError, match="Europe/Amsterdam"):
        parse_time_zone("Europe/Amsterdm")
    with pytest.raises(ValueError, match="not understood"):
        parse_time_zone("Dutch time")


def test_naive_times_without_a_time_zone_are_refused(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-06-01 12:00,1.0\n")
    msg = _error(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'))
    assert "series[0].time_zone" in msg and "line 2 of" in msg and "p.csv" in msg


# -- repeated stamps, irregular stamps ----------------------------------------------------------------------


def test_duplicated_stamps_are_refused_naming_both_lines_or_resolved_as_asked(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-06-01T12:00Z,1.0\n2021-06-01T12:10Z,1.1\n2021-06-01T12:10Z,1.2\n"
                              "2021-06-01T12:20Z,1.3\n")
    body = 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'
    msg = _error(_sidecar(tmp_path, body))
    assert "p.csv: line 4: the time 2021-06-01 12:10:00 UTC appears twice (also on line 3)" in msg
    assert "duplicates" in msg
    first = read_sidecar(_sidecar(tmp_path, body + 'duplicates = "first"\n'))["P.h"]
    last = read_sidecar(_sidecar(tmp_path, body + 'duplicates = "last"\n'))["P.h"]
    np.testing.assert_array_equal(first.values, [1.0, 1.1, 1.3])
    np.testing.assert_array_equal(last.values, [1.0, 1.2, 1.3])


def test_times_out_of_order_are_refused_naming_the_line(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-06-01T12:00Z,1.0\n2021-06-01T11:00Z,1.1\n")
    msg = _error(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'))
    assert "p.csv: line 3: 2021-06-01 11:00:00 UTC comes before 2021-06-01 12:00:00 UTC on line 2" in msg


def test_irregular_stamps_with_seconds_are_kept_as_stamped(tmp_path: Path) -> None:
    stamps = pd.Timestamp("2021-06-01T00:00:07Z") + pd.to_timedelta(np.arange(7) * 31 * 60 + [0, 3, 59, 1, 0, 12, 44],
                                                                    unit="s")
    _write(tmp_path, "p.csv", "time,h\n" + "".join(f"{t.isoformat()},{k / 10}\n" for k, t in enumerate(stamps)))
    s = read_sidecar(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'))["P.h"]
    assert list(s.times) == list(stamps)


# -- depths, datums, units, flags, numbers --------------------------------------------------------------------


LOGGER = "Datum/tijd;Waterdiepte [cm];Kwaliteit\n;cm;-\n01-06-2021 12:00;41,0;0\n01-06-2021 12:15;-999;0\n" \
         "01-06-2021 12:30;43,5;2\n01-06-2021 12:45;250,0;9\n01-06-2021 13:00;44,0;1\n"
LOGGER_SIDE = ('id = "P12.h"\nfile = "logger.csv"\nformat = "csv"\ndelimiter = ";"\ndecimal = ","\nskip_lines = 1\n'
               'time_column = "Datum/tijd"\ntime_format = "%d-%m-%Y %H:%M"\ntime_zone = "UTC+01:00"\n'
               'column = "Waterdiepte [cm]"\nunit = "cm"\nmissing_values = [-999]\n'
               'flag_column = "Kwaliteit"\nflags = { good = [0, 1], doubtful = [2], bad = [9] }\n')


def test_a_depth_logger_becomes_levels_with_its_sensor_zero_unit_and_flags(tmp_path: Path) -> None:
    _write(tmp_path, "logger.csv", LOGGER)
    s = read_sidecar(_sidecar(tmp_path, LOGGER_SIDE + 'measures = "depth"\ndatum_offset = 12.43\n'))["P12.h"]
    assert list(s.times) == list(pd.to_datetime(["2021-06-01 11:00", "2021-06-01 11:30", "2021-06-01 12:00"])
                                 .tz_localize("UTC"))
    np.testing.assert_allclose(s.values, [12.43 + 0.41, 12.43 + 0.435, 12.43 + 0.44])
    assert s.n_missing == 2  # the -999 and the value flagged 9 (bad)
    dropped = read_sidecar(_sidecar(tmp_path, LOGGER_SIDE + 'measures = "depth"\ndatum_offset = 12.43\n'
                                              'drop_doubtful = true\n'))["P12.h"]
    assert len(dropped) == 2 and dropped.n_missing == 3


def test_a_depth_series_without_a_datum_is_refused_naming_the_sidecar_line(tmp_path: Path) -> None:
    _write(tmp_path, "logger.csv", LOGGER)
    side = _sidecar(tmp_path, LOGGER_SIDE + 'measures = "depth"\n')
    msg = _error(side)
    assert msg.startswith(f"{side}: series[0].measures: line 16: "), msg
    assert "datum_offset" in msg and "sensor's zero" in msg


def test_a_flag_the_sidecar_does_not_list_is_refused_naming_the_line(tmp_path: Path) -> None:
    _write(tmp_path, "logger.csv", LOGGER.replace("44,0;1", "44,0;X"))
    msg = _error(_sidecar(tmp_path, LOGGER_SIDE))
    assert "logger.csv: line 7: flag 'X' in column 'Kwaliteit' is not listed" in msg and "bad: '9'" in msg


def test_a_decimal_comma_without_its_setting_is_refused_with_the_hint(tmp_path: Path) -> None:
    _write(tmp_path, "logger.csv", LOGGER)
    msg = _error(_sidecar(tmp_path, LOGGER_SIDE.replace('decimal = ","\n', "")))
    assert "logger.csv: line 3: '41,0' is not a number (a decimal comma? say decimal = ',')" in msg


@pytest.mark.parametrize(("unit", "factor"), [("m", 1.0), ("cm", 0.01), ("mm", 0.001), ("m NAP", 1.0)])
def test_level_units_convert_to_metres(tmp_path: Path, unit: str, factor: float) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-06-01T12:00Z,150\n")
    s = read_sidecar(_sidecar(tmp_path, f'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\nunit = "{unit}"\n'
                                        'datum_offset = -2.33\n'))["P.h"]
    assert s.values[0] == pytest.approx(150 * factor - 2.33)


def test_a_discharge_unit_on_a_level_and_a_datum_on_a_discharge_are_refused(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,q\n2021-06-01T12:00Z,150\n")
    msg = _error(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "q"\nunit = "l/s"\n'))
    assert "series[0].unit: line 6: 'l/s' is a unit of discharges" in msg
    msg = _error(_sidecar(tmp_path, 'id = "P.Q"\nfile = "p.csv"\nformat = "csv"\ncolumn = "q"\nunit = "l/s"\n'
                                    'datum_offset = 1.0\n'))
    assert "series[0].datum_offset: line 7: a discharge has no datum" in msg
    s = read_sidecar(_sidecar(tmp_path, 'id = "P.Q"\nfile = "p.csv"\nformat = "csv"\ncolumn = "q"\nunit = "l/s"\n'))
    assert s["P.Q"].values[0] == pytest.approx(0.15)


# -- the sidecar itself ----------------------------------------------------------------------------------------


def test_a_misspelt_sidecar_field_is_named_with_its_line_and_a_suggestion(tmp_path: Path) -> None:
    side = _sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\ntimezone = "UTC"\n')
    msg = _error(side)
    assert msg == f"{side}: series[0].timezone: line 6: unknown field 'timezone'; did you mean 'time_zone'?"


def test_sidecar_problems_name_file_field_and_line(tmp_path: Path) -> None:
    side = _sidecar(tmp_path, 'id = "P.level"\nfile = "p.csv"\nformat = "csv"\n')
    assert "series[0].id: line 2:" in _error(side) and "<station>.<quantity>" in _error(side)
    side = _sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "excel"\n')
    assert "series[0].format: line 4: 'excel' is not allowed" in _error(side)
    side = _sidecar(tmp_path, 'id = "P.h"\nfile = "missing.csv"\nformat = "csv"\ncolumn = "h"\n')
    assert "series[0].file: line 3: 'missing.csv' not found" in _error(side)
    side = _write(tmp_path, "empty.toml", "# nothing\n")
    assert "no [[series]] table" in _error(side)
    side = _write(tmp_path, "broken.toml", "[[series]\nid = 1\n")
    assert "not valid TOML" in _error(side)
    assert SIDECAR_SCHEMA["properties"]["series"]["type"] == "array"


def test_the_same_series_twice_is_refused(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,h\n2021-06-01T12:00Z,1\n")
    body = 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "h"\n'
    side = _write(tmp_path, "two.toml", f"[[series]]\n{body}\n[[series]]\n{body}")
    assert "series[1].id: line 8: series 'P.h' is described twice" in _error(side)


def test_a_csv_column_that_is_not_in_the_header_gets_a_suggestion(tmp_path: Path) -> None:
    _write(tmp_path, "p.csv", "time,level_cm\n2021-06-01T12:00Z,1\n")
    msg = _error(_sidecar(tmp_path, 'id = "P.h"\nfile = "p.csv"\nformat = "csv"\ncolumn = "level cm"\n'))
    assert "p.csv: line 1: the header has no value column 'level cm'; did you mean 'level_cm'?" in msg


def test_read_observations_takes_any_known_file_by_its_suffix(tmp_path: Path) -> None:
    _write(tmp_path, "obs.csv", "time,P.h\n2021-06-01T12:00Z,1.5\n")
    assert read_observations(tmp_path / "obs.csv")["P.h"].values[0] == 1.5
    with pytest.raises(CaseError, match=r"ending in \.csv, \.xml, \.toml"):
        read_observations(tmp_path / "obs.xlsx")


def test_a_long_table_of_many_gauges_is_read_one_gauge_at_a_time(tmp_path: Path) -> None:
    _write(tmp_path, "export.csv", "location,time,value\nG01,2021-06-01T12:00Z,1.0\nG02,2021-06-01T12:00Z,2.0\n"
                                   "G01,2021-06-01T12:31:07Z,1.1\nG02,2021-06-01T12:45Z,2.1\n")
    body = ('format = "csv"\nfile = "export.csv"\ntime_column = "time"\ncolumn = "value"\n'
            'station_column = "location"\n')
    side = _write(tmp_path, "two.toml", f'[[series]]\nid = "G01.h"\n{body}station = "G01"\n\n'
                                        f'[[series]]\nid = "G02.h"\n{body}station = "G02"\n')
    obs = read_sidecar(side)
    np.testing.assert_array_equal(obs["G01.h"].values, [1.0, 1.1])
    assert obs["G01.h"].times[1] == pd.Timestamp("2021-06-01T12:31:07Z")
    np.testing.assert_array_equal(obs["G02.h"].values, [2.0, 2.1])
    wrong = _write(tmp_path, "wrong.toml", f'[[series]]\nid = "G03.h"\n{body}station = "G03"\n')
    assert "export.csv: no row has 'G03' in column 'location' (it holds 'G01', 'G02')" in _error(wrong)


def test_the_how_to_example_logger_reads_as_the_guide_says() -> None:
    folder = Path(__file__).resolve().parents[2] / "docs" / "howto" / "example-sensors"
    s = read_sidecar(folder / "P0029.toml")["0029.h_up"]
    rows = [line.split(";") for line in (folder / "logger_P0029.csv").read_text().splitlines()[2:]]
    # every 15 minutes in UTC across the night the clocks went back (one value flagged 9 / -999 is missing)
    steps = np.diff(s.times.asi8) // 10**9
    assert set(steps.tolist()) == {900, 1800} and (steps == 1800).sum() == 1 and s.n_missing == 1
    assert len(rows) == 292 + 1 and sum(r[2] == "-999" for r in rows) == 1
    assert s.times[0] == pd.Timestamp("2010-10-29T22:00Z")         # 30-10-2010 00:00 CEST
    first = float(rows[0][2].replace(",", "."))
    assert s.values[0] == pytest.approx(first / 100 + 6.02)
    assert s.sigma == 0.02
