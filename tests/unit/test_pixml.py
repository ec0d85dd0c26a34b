"""Delft-FEWS PI-XML: reading observations (names, time zones, missing values, units, unsafe XML) and writing."""

from __future__ import annotations

import logging
import pickle
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.io import STANDARD_CONVERSIONS, PiXmlError, read_pixml, read_pixml_series, write_pixml
from rivercal.io.pixml import PiSeries, _norm_unit, write_pixml_series
from tests.conftest import assert_valid_pi

MAPPING = {("0028", "H.up"): "0028.h_up", ("0028", "H.down"): "0028.h_down", ("0031", "Q"): "0031.Q"}


def series_xml(location: str, parameter: str, events: list[tuple[str, str, str | None, str | None]], *,
               units: str | None = "m", miss_val: str | None = "-999.0", qualifier: str | None = None) -> str:
    head = [f"<type>instantaneous</type><locationId>{location}</locationId><parameterId>{parameter}</parameterId>"]
    if qualifier:
        head.append(f"<qualifierId>{qualifier}</qualifierId>")
    head.append('<timeStep unit="second" multiplier="3600"/>')
    head.append(f'<startDate date="{events[0][0]}" time="{events[0][1]}"/>')
    head.append(f'<endDate date="{events[-1][0]}" time="{events[-1][1]}"/>')
    if miss_val is not None:
        head.append(f"<missVal>{miss_val}</missVal>")
    if units is not None:
        head.append(f"<units>{units}</units>")
    body = []
    for date, time, value, flag in events:
        attrs = f'date="{date}" time="{time}"'
        attrs += f' value="{value}"' if value is not None else ""
        attrs += f' flag="{flag}"' if flag is not None else ""
        body.append(f"<event {attrs}/>")
    return f"<series><header>{''.join(head)}</header>{''.join(body)}</series>"


def pi_file(path: Path, *series: str, time_zone: str | None = "0.0") -> Path:
    zone = f"<timeZone>{time_zone}</timeZone>" if time_zone is not None else ""
    path.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<TimeSeries xmlns="http://www.wldelft.nl/fews/PI" '
                    'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" version="1.2">'
                    f"{zone}{''.join(series)}</TimeSeries>", encoding="utf-8")
    return path


def hourly_events(day: str, values: list[str | None], flags: list[str | None] | None = None):
    flags = flags or ["0"] * len(values)
    return [(day, f"{h:02d}:00:00", v, f) for h, (v, f) in enumerate(zip(values, flags, strict=True))]


def test_series_are_mapped_to_ids_in_the_mappings_order(tmp_path: Path) -> None:
    path = pi_file(tmp_path / "obs.xml",
                   series_xml("0031", "Q", hourly_events("2010-11-01", ["1.5", "1.6", "1.7"]), units="m3/s"),
                   series_xml("0028", "H.up", hourly_events("2010-11-01", ["7.31", "7.32", "7.33"]), units="m NAP"),
                   series_xml("9999", "T.air", hourly_events("2010-11-01", ["5.0"]), units="degC"))
    obs = read_pixml(path, MAPPING, sigma={"h_up": 0.01})
    assert obs.ids == ["0028.h_up", "0031.Q"]
    assert obs["0028.h_up"].values.tolist() == [7.31, 7.32, 7.33]
    assert obs["0028.h_up"].sigma == 0.01 and obs["0031.Q"].sigma is None  # sigma replaces DEFAULT_SIGMA
    assert obs["0031.Q"].times[0] == pd.Timestamp("2010-11-01T00:00:00Z")
    assert obs["0031.Q"].source == str(path)
    with pytest.raises(PiXmlError, match=r"series not in the mapping: 9999/T\.air"):
        read_pixml(path, MAPPING, unmapped="error")
    with pytest.raises(PiXmlError, match=r"no series of the file is in the mapping \(the file has: 0031/Q, 0028"):
        read_pixml(path, {("1", "H"): "1.h"})


def test_times_are_converted_from_the_files_time_zone_to_utc(tmp_path: Path) -> None:
    events = [("2010-11-01", "01:00:00", "7.3", "0"), ("2010-11-01", "02:30:00", "7.4", "0")]
    cet = read_pixml(pi_file(tmp_path / "cet.xml", series_xml("0028", "H.up", events), time_zone="1.0"), MAPPING)
    assert list(cet["0028.h_up"].times) == [pd.Timestamp("2010-11-01T00:00Z"), pd.Timestamp("2010-11-01T01:30Z")]
    india = read_pixml(pi_file(tmp_path / "ist.xml", series_xml("0028", "H.up", events), time_zone="5.5"), MAPPING)
    assert india["0028.h_up"].times[0] == pd.Timestamp("2010-10-31T19:30Z")
    west = read_pixml(pi_file(tmp_path / "w.xml", series_xml("0028", "H.up", events), time_zone="-5"), MAPPING)
    assert west["0028.h_up"].times[0] == pd.Timestamp("2010-11-01T06:00Z")
    none = read_pixml(pi_file(tmp_path / "gmt.xml", series_xml("0028", "H.up", events), time_zone=None), MAPPING)
    assert none["0028.h_up"].times[0] == pd.Timestamp("2010-11-01T01:00Z")  # the PI default is GMT
    with pytest.raises(PiXmlError, match="<timeZone> 'CET' is not a number of hours"):
        read_pixml(pi_file(tmp_path / "bad.xml", series_xml("0028", "H.up", events), time_zone="CET"), MAPPING)


def test_missing_and_unreliable_values_are_dropped_and_counted(tmp_path: Path, caplog) -> None:
    values = ["7.30", "-999.0", "NaN", None, "7.34", "7.35", "7.36", "7.37"]
    flags = ["0", "0", "0", "0", "6", "3", "9", None]
    path = pi_file(tmp_path / "gaps.xml", series_xml("0028", "H.up", hourly_events("2010-11-01", values, flags)))
    with caplog.at_level(logging.INFO, logger="rivercal.io.pixml"):
        obs = read_pixml(path, MAPPING)
    s = obs["0028.h_up"]
    assert s.values.tolist() == [7.30, 7.35, 7.37]  # the doubtful 7.35 (flag 3) is kept
    assert s.n_missing == 5
    assert [t.hour for t in s.times] == [0, 5, 7]
    assert "0028.h_up: 3 values; dropped 3 missing (missVal or NaN) and 2 flagged unreliable; 1 doubtful kept" \
        in caplog.text
    strict = read_pixml(path, MAPPING, drop_doubtful=True)
    assert strict["0028.h_up"].values.tolist() == [7.30, 7.37]


def test_unit_mismatches_are_errors_naming_file_series_and_unit(tmp_path: Path) -> None:
    path = pi_file(tmp_path / "units.xml",
                   series_xml("0028", "H.up", hourly_events("2010-11-01", ["731", "732"]), units="cm"),
                   series_xml("0031", "Q", hourly_events("2010-11-01", ["1500", "1600"]), units="l/s"),
                   series_xml("0028", "H.down", hourly_events("2010-11-01", ["6.9", "6.9"]), units="m"))
    with pytest.raises(PiXmlError) as err:
        read_pixml(path, MAPPING)
    text = str(err.value)
    assert text.startswith(f"{path}: 2 series cannot be used:")
    assert ("series locationId=0028 parameterId=H.up (-> 0028.h_up): unit 'cm' where 'm' is expected for quantity "
            "h_up; pass conversions={('cm', 'm'): 0.01} (or STANDARD_CONVERSIONS) to convert") in text
    assert "series locationId=0031 parameterId=Q (-> 0031.Q): unit 'l/s' where 'm3/s' is expected" in text
    assert err.value.file == str(path)
    converted = read_pixml(path, MAPPING, conversions=STANDARD_CONVERSIONS)
    assert converted["0028.h_up"].values.tolist() == pytest.approx([7.31, 7.32])
    assert converted["0031.Q"].values.tolist() == pytest.approx([1.5, 1.6])
    one = pi_file(tmp_path / "one.xml", series_xml("0028", "H.up", hourly_events("2010-11-01", ["7"]), units="ft"))
    with pytest.raises(PiXmlError, match=r"unit 'ft' where 'm' is expected for quantity h_up; convert the file"):
        read_pixml(one, MAPPING)


@pytest.mark.parametrize(("text", "norm"), [("m", "m"), ("m NAP", "m"), ("m+NAP", "m"), ("metre", "m"),
                                            ("m3/s", "m3/s"), ("m³/s", "m3/s"), ("m3 s-1", "m3/s"),
                                            ("m^3/s", "m3/s"), ("M3.S-1", "m3/s"), ("cm", "cm"), ("l/s", "l/s")])
def test_unit_spellings(text: str, norm: str) -> None:
    assert _norm_unit(text) == norm


def test_a_billion_laughs_file_is_refused(tmp_path: Path) -> None:
    entities = ['<!ENTITY lol "lol">'] + [f'<!ENTITY lol{i} "{("&lol" + str(i - 1) + ";") * 10}">'
                                          for i in range(1, 10)]
    entities[1] = '<!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">'
    path = tmp_path / "lol.xml"
    path.write_text('<?xml version="1.0"?>\n<!DOCTYPE TimeSeries [\n' + "\n".join(entities) + "\n]>\n"
                    '<TimeSeries xmlns="http://www.wldelft.nl/fews/PI"><series><header>'
                    "<locationId>&lol9;</locationId></header></series></TimeSeries>", encoding="utf-8")
    with pytest.raises(PiXmlError, match="refused to parse: the file declares a DTD or XML entities") as err:
        read_pixml(path, MAPPING)
    assert str(err.value).startswith(str(path))
    assert "billion laughs" in str(err.value)


def test_an_external_entity_file_is_refused(tmp_path: Path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("password")
    path = tmp_path / "xxe.xml"
    path.write_text(f'<?xml version="1.0"?>\n<!DOCTYPE t [<!ENTITY x SYSTEM "file://{secret}">]>\n'
                    '<TimeSeries xmlns="http://www.wldelft.nl/fews/PI"><timeZone>&x;</timeZone></TimeSeries>')
    with pytest.raises(PiXmlError, match="refused to parse"):
        read_pixml_series(path)


def test_broken_and_foreign_files_are_reported(tmp_path: Path) -> None:
    broken = tmp_path / "broken.xml"
    broken.write_text('<TimeSeries xmlns="http://www.wldelft.nl/fews/PI"><series>')
    with pytest.raises(PiXmlError, match=r"broken.xml: not well-formed XML \(no element found: line 1"):
        read_pixml(broken, MAPPING)
    other = tmp_path / "other.xml"
    other.write_text("<Locations/>")
    with pytest.raises(PiXmlError, match="root element is <Locations>, not <TimeSeries>"):
        read_pixml(other, MAPPING)
    with pytest.raises(PiXmlError, match="cannot read the file"):
        read_pixml(tmp_path / "missing.xml", MAPPING)
    bad_value = pi_file(tmp_path / "v.xml", series_xml("0028", "H.up", hourly_events("2010-11-01", ["7.3", "n/a"])))
    with pytest.raises(PiXmlError, match=r"series locationId=0028 parameterId=H.up: event 2 \(2010-11-01 01:00:00\): "
                                         r"value 'n/a' is not a number"):
        read_pixml(bad_value, MAPPING)
    bad_time = pi_file(tmp_path / "t.xml", series_xml("0028", "H.up", [("2010-11-31", "00:00:00", "7.3", "0")]))
    with pytest.raises(PiXmlError, match="event 1: '2010-11-31 00:00:00' is not a date and time"):
        read_pixml(bad_time, MAPPING)
    twice = pi_file(tmp_path / "twice.xml", series_xml("0028", "H.up", hourly_events("2010-11-01", ["7.3"])),
                    series_xml("0028", "H.up", hourly_events("2010-11-01", ["7.4"]), qualifier="validated"))
    with pytest.raises(PiXmlError, match=r"0028\.h_up: time 2010-11-01T00:00:00\+00:00 occurs more than once"):
        read_pixml(twice, MAPPING)


def test_the_error_survives_pickling(tmp_path: Path) -> None:
    err = PiXmlError("unit 'cm'", file="a.xml", field="series x")
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is PiXmlError and str(back) == str(err) == "a.xml: series x: unit 'cm'"


def test_a_written_forecast_reads_back(tmp_path: Path) -> None:
    times = pd.date_range("2010-11-01T06:00Z", periods=49, freq="h")
    forecast = pd.DataFrame({"0028.h_up": np.linspace(7.3, 7.5, 49), "0031.Q": np.linspace(1.5, 2.5, 49)},
                            index=times)
    forecast.iloc[10, 1] = np.nan
    ids = {"0028.h_up": ("0028", "H.up"), "0031.Q": ("0031", "Q")}
    path = write_pixml(tmp_path / "forecast.xml", forecast, ids=ids, time_zone=1.0, forecast_date=times[0])
    text = path.read_text(encoding="utf-8")
    assert '<forecastDate date="2010-11-01" time="07:00:00" />' in text
    assert '<timeStep unit="second" multiplier="3600" />' in text
    assert "<timeZone>1.0</timeZone>" in text
    raw = read_pixml_series(path)
    assert [(s.location_id, s.parameter_id, s.units) for s in raw] == [("0028", "H.up", "m"), ("0031", "Q", "m3/s")]
    back = read_pixml(path, MAPPING)
    assert back["0028.h_up"].times.equals(pd.DatetimeIndex(times))
    assert back["0028.h_up"].values == pytest.approx(forecast["0028.h_up"].to_numpy())
    assert (len(back["0031.Q"]), back["0031.Q"].n_missing) == (48, 1)


def test_written_files_validate_against_the_pi_schema(tmp_path: Path, pi_schema) -> None:
    """Forecasts and estimate series (qualifiers, flags, comments, missing values) validate (pi_timeseries.xsd)."""
    schema = pi_schema("pi_timeseries.xsd")
    times = pd.date_range("2010-11-01T06:00Z", periods=5, freq="h")
    forecast = pd.DataFrame({"0028.h_up": [7.3, np.nan, 7.31, 7.32, 7.33]}, index=times)
    path = write_pixml(tmp_path / "f.xml", forecast, time_zone=1.0, forecast_date=times[0], qualifiers=("dss",))
    assert_valid_pi(schema, path)
    assert "moduleInstanceId" not in path.read_text(encoding="utf-8")
    uneven = pd.DatetimeIndex(["2010-11-01T06:00Z", "2010-11-02T06:00Z", "2010-11-04T06:00Z"])
    est = PiSeries("dommel", "FA", ("estimate",), "instantaneous", "m^(1/3)/s", float("nan"), uneven,
                   np.array([16.0, np.nan, 24.9]), np.array([0, -1, 3]), ("", "", "held: the window cannot see FA"))
    path = write_pixml_series(tmp_path / "e.xml", [est], time_zone=-5.5)
    assert_valid_pi(schema, path)
    back = read_pixml_series(path)[0]
    assert back.qualifier_ids == ("estimate",) and back.comments == est.comments
    assert back.times.equals(uneven) and back.flags.tolist() == [0, -1, 3]
    assert np.array_equal(back.values, est.values, equal_nan=True)
    with pytest.raises(ValueError, match="at least one event"):
        write_pixml_series(tmp_path / "none.xml", [est.__class__(*[getattr(est, f) for f in
                                                                  ("location_id", "parameter_id", "qualifier_ids",
                                                                   "series_type", "units", "miss_val")],
                                                                pd.DatetimeIndex([], tz="UTC"), np.array([]),
                                                                np.array([], dtype=int))])
