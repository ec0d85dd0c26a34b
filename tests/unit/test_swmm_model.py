"""EPA SWMM 5 behind the model contract (the real engine, swmm-toolkit), on the packaged case dommel-swmm."""

from __future__ import annotations

import pandas as pd
import pytest

from rivercal.models import FileState, load_model
from rivercal.models.swmm import SwmmModel, SwmmRunError
from rivercal.models.swmm.inp import InpFile
from rivercal.models.swmm.output import read_swmm_output

DAY = pd.Timedelta("1D")


@pytest.fixture(scope="module")
def swmm() -> SwmmModel:
    return load_model("dommel-swmm")


def test_the_swmm_case_declares_its_quantities_stations_and_calibration(swmm) -> None:
    q = swmm.quantities
    assert q["roughness:factor"].unit == "-" and q["weir:ZL1-3014.crest_level"].unit == "m"
    assert {"roughness:group:ZL12", "roughness:group:ZL25"} <= set(q)
    defaults = swmm.default_parameters()
    assert defaults["weir:ZL1-3014.crest_level"] == pytest.approx(10.45)  # the dommel crest
    assert defaults["conduit:ZL12_c38.roughness"] == pytest.approx(1 / 16)
    assert swmm.dt == 30.0 and swmm.output_interval == 3600.0 and swmm.spinup == 96.0
    assert swmm.numerical_noise == 0.0005  # the file's HEAD_TOLERANCE, m
    assert swmm.observables == ["0028.h_up", "0028.h_down", "0040.h_up", "0040.h_down", "0029.h_up", "0029.h_down",
                                "0029.Q", "0030.h_up", "0030.h_down", "0031.h_up", "0031.h_down"]
    assert {"FR", "FA", "F1", "Wc", "Wd"} <= set(swmm.calibration.names) and "moderate" in swmm.calibration.windows
    assert defaults["friction:global"] == pytest.approx(16.0) and q["friction:branch:ZL12"].unit == "m^(1/3)/s"
    # the crest may not go below the inlet node's invert
    low = q["weir:ZL1-3014.crest_level"].min
    with pytest.raises(ValueError, match=r"weir:ZL1-3014\.crest_level: value .* is outside its range"):
        swmm.simulate({"weir:ZL1-3014.crest_level": low - 0.1}, end=swmm.start + DAY)
    with pytest.raises(ValueError, match="no settable quantity 'friction:branch:ZL99'"):
        swmm.simulate({"friction:branch:ZL99": 20.0}, end=swmm.start + DAY)


def test_a_run_writes_exactly_the_quantities_it_is_given(swmm) -> None:
    text = swmm.render({"roughness:factor": 1.5, "roughness:group:ZL12": 2.0, "conduit:ZL25_c65.roughness": 0.05,
                        "weir:ZL1-3014.crest_level": 10.30}, swmm.start, swmm.start + DAY, 3600.0, hot=False)
    inp = InpFile(text)
    conduits = inp.table("CONDUITS")
    assert float(conduits["ZL1_0000_3030_c0"].tokens[4]) == pytest.approx(1.5 / 16)
    assert float(conduits["ZL12_c38"].tokens[4]) == pytest.approx(3.0 / 16)  # global factor × group factor
    assert float(conduits["ZL25_c65"].tokens[4]) == pytest.approx(0.075)  # its own n × the global factor
    weir = inp.table("WEIRS")["ZL1-3014"].tokens
    assert float(weir[4]) + inp.node_inverts()[weir[1]] == pytest.approx(10.30)
    # Strickler k_s: the most specific value wins (conduit over branch tag over global), then the factors
    text = swmm.render({"friction:global": 25.0, "friction:branch:ZL12": 20.0, "roughness:factor": 2.0,
                        "conduit:ZL25_c65.roughness": 0.05}, swmm.start, swmm.start + DAY, 3600.0, hot=False)
    conduits = InpFile(text).table("CONDUITS")
    assert [float(conduits[c].tokens[4]) for c in ("ZL1_0000_3030_c0", "ZL12_c38", "ZL25_c65")] == pytest.approx(
        [2.0 / 25.0, 2.0 / 20.0, 0.1])
    assert inp.option("START_DATE") == "09/20/2010" and inp.option("REPORT_STEP") == "01:00:00"


def test_hot_starts_continue_a_run_and_states_stay_with_their_model(swmm) -> None:
    whole, _ = swmm.simulate({}, end=swmm.start + 2 * DAY)
    first, state = swmm.simulate({}, end=swmm.start + DAY)
    assert isinstance(state, FileState) and state.time == swmm.start + DAY
    again = swmm.load_state(swmm.save_state(state), swmm.state_format)
    second, _ = swmm.simulate({}, start=swmm.start + DAY, end=swmm.start + 2 * DAY, state=again)
    assert second.series.index[0] == swmm.start + DAY and len(second.series) == 25
    # the hot start's first row is SWMM's state after reading the hotstart file: the cold run's last row
    assert (second.series.iloc[0] - first.series.iloc[-1]).abs().max() < 1e-5
    # SWMM's hotstart file does not hold every internal variable: the continuation stays within 1 cm
    assert (second.series - whole.series.loc[second.series.index]).abs().max().max() < 0.01
    with pytest.raises(ValueError, match="written by"):
        other = FileState(time=state.time, files=state.files, origin="swmm:another")
        swmm.load_state(other.to_bytes(), swmm.state_format)
    with pytest.raises(ValueError, match="not 'rivercal-swmm-hotstart-1'"):
        swmm.load_state(b"", "rivercal-engine-state-npz-1")


def test_a_failed_swmm_run_names_its_folder_and_swmm_s_message(tmp_path, swmm) -> None:
    bad = tmp_path / "bad.inp"
    bad.write_text(swmm.inp_path.read_text().replace("ZL1-3014_up ZL1-3014_dn TRANSVERSE",
                                                     "ZL1-3014_up NOWHERE TRANSVERSE"))
    model = SwmmModel(bad, {"x.h": "node:ZL1_up"}, name="bad", start=swmm.start, end=swmm.end, runs_dir=tmp_path)
    with pytest.raises(SwmmRunError, match=r"SWMM run in .*swmm-bad-.* failed: .*(ERROR|Error).*") as info:
        model.simulate({}, end=swmm.start + DAY)
    assert (tmp_path / info.value.run_dir).is_dir()


def test_the_output_reader_names_a_truncated_file(tmp_path, swmm) -> None:
    with pytest.raises(ValueError, match="no such SWMM output file"):
        read_swmm_output(tmp_path / "none.out", {"a.h": "node:x"})
    (tmp_path / "junk.out").write_bytes(b"\x00" * 100)
    with pytest.raises(ValueError, match=r"junk\.out: not a SWMM output file"):
        read_swmm_output(tmp_path / "junk.out", {"a.h": "node:x"})
    result = swmm.render({}, swmm.start, swmm.start + DAY, 3600.0, hot=False)
    (tmp_path / "m.inp").write_text(result)
    from swmm.toolkit import solver

    solver.swmm_run(str(tmp_path / "m.inp"), str(tmp_path / "m.rpt"), str(tmp_path / "m.out"))
    whole = (tmp_path / "m.out").read_bytes()
    full = read_swmm_output(tmp_path / "m.out", {"a.h": "node:ZL1-3014_up"})
    assert len(full) == 24 and full.index[0] == swmm.start + pd.Timedelta("1h")  # one step after the start
    (tmp_path / "cut.out").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(ValueError, match=r"cut\.out: the SWMM output is truncated"):
        read_swmm_output(tmp_path / "cut.out", {"a.h": "node:ZL1-3014_up"})
    with pytest.raises(ValueError, match="has no node 'nowhere'"):
        read_swmm_output(tmp_path / "m.out", {"a.h": "node:nowhere"})
