"""CF NetCDF outputs carry station ids and positions, the CRS and the vertical datum, and pass a CF checker."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from rivercal.case import case_from_dict, load_case
from rivercal.engine.simulator import Simulator
from rivercal.errors import CaseError
from rivercal.io.cf import add_stations, write_netcdf
from rivercal.store import Store, to_xarray
from tests.conftest import channel_case
from tests.dashboard_store import build_store

#: The RD New origin (x 155000 m, y 463000 m) in WGS 84 (the Amersfoort tower; Schreutelkamp and Strang van
#: Hees, "Benaderingsformules voor de transformatie tussen RD- en WGS84-kaartcoördinaten", 2001).
RD_ORIGIN_WGS84 = (52.15517440, 5.38720621)


def cf_problems(path: Path) -> list[str]:
    """The high-priority (must-fix) findings of the IOOS compliance checker's CF-1.8 suite, run offline."""
    from compliance_checker.runner import CheckSuite, ComplianceChecker

    CheckSuite.load_all_available_checkers()
    report = path.with_suffix(".json")
    ComplianceChecker.run_checker(str(path), ["cf:1.8"], 0, "normal", output_filename=str(report),
                                  output_format="json")
    result = json.loads(report.read_text())["cf:1.8"]
    assert len(result["high_priorities"]) > 10  # the suite ran its checks
    return [f"{p['name']}: {'; '.join(p['msgs'])}" for p in result["high_priorities"]
            if p["value"][0] < p["value"][1] or p["msgs"]]


def rd_case(tmp_path: Path, **meta):
    data = channel_case(stations=[{"id": "origin", "branch": "B", "chainage": 0.0, "quantities": ["h", "Q"]},
                                  {"id": "mid", "branch": "B", "chainage": 2500.0, "quantities": ["h"]}])
    data["case"].update(meta)
    data["nodes"] = [{"id": "up", "x": 155000.0, "y": 463000.0}, {"id": "down", "x": 160000.0, "y": 463000.0}]
    return case_from_dict(data, tmp_path)


def test_simulated_series_carry_stations_crs_and_datum_and_pass_the_cf_checker(tmp_path: Path) -> None:
    case = rd_case(tmp_path, crs="EPSG:28992", vertical_datum="NAP")
    sim = Simulator(case)
    result, _ = sim.simulate({}, end=sim.start + pd.Timedelta("6h"))
    path = write_netcdf(add_stations(result.to_dataset(), case), tmp_path / "series.nc")
    assert cf_problems(path) == []
    ds = xr.open_dataset(path)
    assert ds["level_station_id"].values.tolist() == ["origin", "mid"]
    assert ds["level_x"].values.tolist() == [155000.0, 157500.0] and ds["level_y"].values.tolist() == [463000.0] * 2
    origin = (float(ds["level_lat"][0]), float(ds["level_lon"][0]))
    assert origin == pytest.approx(RD_ORIGIN_WGS84, abs=1e-5)  # ~1 m, the approximation formulas' accuracy
    assert ds["discharge_station_id"].values.tolist() == ["origin"]
    assert ds["crs"].attrs["epsg_code"] == "EPSG:28992" and "RD New" in ds["crs"].attrs["crs_wkt"]
    assert ds["water_level"].attrs["vertical_datum"] == "NAP" and "(m NAP)" in ds["water_level"].attrs["long_name"]
    import netCDF4

    with netCDF4.Dataset(path) as raw:
        assert set(raw["water_level"].coordinates.split()) >= {"level_station_id", "level_lat", "level_lon"}
    assert np.allclose(ds["water_level"].values, result.series[["origin.h", "mid.h"]].to_numpy().T)


def test_the_stores_forecasts_and_estimates_pass_the_cf_checker(tmp_path: Path) -> None:
    """The report's run.nc: forecasts per station (dommel: no CRS, its own datum) and the estimates."""
    db = build_store(tmp_path / "run.sqlite", 3)
    with Store(db, readonly=True) as store:
        ds = add_stations(to_xarray(store, store.get_run("dash")), load_case("dommel"))
    path = write_netcdf(ds, tmp_path / "run.nc")
    assert cf_problems(path) == []
    back = xr.open_dataset(path)
    assert "crs" not in back and "level_lat" not in back  # no CRS declared: no invented positions
    assert back["level_station_id"].values.tolist()[:2] == ["0028", "0028"]
    assert "not declared" in back["water_level"].attrs["vertical_datum"]
    assert back["FA"].attrs["units_text"] == "m^(1/3)/s" and "units" not in back["FA"].attrs


@pytest.mark.parametrize(("value", "words"), [
    ("EPSG:999999", "is not a coordinate reference system"),
    ("EPSG:4326", "is not a projected system"),
])
def test_a_bad_crs_is_refused_at_load_naming_the_field(tmp_path: Path, value: str, words: str) -> None:
    with pytest.raises(CaseError, match=words) as info:
        rd_case(tmp_path, crs=value)
    assert "case.crs" in str(info.value)


def test_stations_at_every_kind_of_structure_are_placed_and_a_network_without_map_coordinates_writes_ids(
        tmp_path: Path) -> None:
    from rivercal.network.coordinates import MissingCoordinates, station_coordinates

    data = channel_case(stations=[{"id": "at_orifice", "structure": "O1", "quantities": ["h_up", "Q"]},
                                  {"id": "at_bridge", "structure": "BR1"},
                                  {"id": "mid", "branch": "B", "chainage": 2500.0, "quantities": ["h"]}])
    data["profiles"].append({"id": "opening", "type": "rectangular", "width": 8.0, "height": 4.0, "closed": False})
    data["orifices"] = [{"id": "O1", "branch": "B", "chainage": 1000.0, "crest_level": 0.5, "crest_width": 5.0,
                         "gate_lower_edge_level": 2.0}]
    data["bridges"] = [{"id": "BR1", "branch": "B", "chainage": 4000.0, "profile": "opening", "bed_level": 0.1,
                        "length": 10.0}]
    case = case_from_dict(data, tmp_path)
    where = station_coordinates(case.network)
    assert where == {"at_orifice": (1000.0, 0.0), "at_bridge": (4000.0, 0.0), "mid": (2500.0, 0.0)}

    data["nodes"] = [{"id": "up"}, {"id": "down"}]  # map coordinates are optional in a case
    bare = case_from_dict(data, tmp_path / "bare")
    with pytest.raises(MissingCoordinates, match=r"'down'|'up'"):
        station_coordinates(bare.network)
    sim = Simulator(bare)
    result, _ = sim.simulate({}, end=sim.start + pd.Timedelta("1h"))
    ds = xr.open_dataset(write_netcdf(add_stations(result.to_dataset(), bare), tmp_path / "bare.nc"))
    assert ds["level_station_id"].values.tolist() == ["at_orifice", "at_bridge", "at_bridge", "mid"]
    assert "level_x" not in ds and "level_lat" not in ds
