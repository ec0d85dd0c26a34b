"""``rivercal advise gauges`` as a user runs it: the advice on dommel, its files, and bad input named."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.cli import rivercal

WINDOW = "2010-09-30/2010-10-02"


@pytest.fixture(scope="module")
def advice(tmp_path_factory) -> tuple[dict, Path]:
    out = tmp_path_factory.mktemp("advise")
    done = rivercal("advise", "gauges", "dommel", "--params", "W4,W6,FA", "--window", WINDOW, "--candidates",
                    "structures", "--forecast", "0029.Q", "--workers", "1", "--json", "--out", str(out))
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout), out


def test_the_advice_finds_the_gauges_of_the_unseen_crests(advice) -> None:
    summary, out = advice
    # with the five stations neither W4 (ZL1-5930) nor W6 (ZL12-1880) is seen: no station is near them
    assert summary["before"]["verdict"] == {"W4": "not identifiable", "W6": "not identifiable", "FA": "identifiable"}
    # the advice adds a level in the pool each of the two crests holds (between it and the weir upstream),
    # and then every parameter is identifiable
    assert summary["enough"] == 2
    chosen = {s["candidate"] for s in summary["steps"]}
    assert len(chosen & {"ZL1-5126_down", "ZL1-5930_up"}) == 1
    assert len(chosen & {"ZL12-45_down", "ZL12-1880_up"}) == 1
    assert set(summary["after"]["verdict"].values()) == {"identifiable"}
    assert summary["after"]["posterior_std"]["W4"] < 0.1 * summary["before"]["posterior_std"]["W4"]
    assert summary["targets"] == ["0029.Q"]
    assert summary["jacobian_runs"] == 4  # one Jacobian of every candidate's series: p + 1 runs
    for key in ("candidates", "steps", "before", "after", "worth_map", "summary"):
        assert Path(summary["files"][key]).is_file()
    assert json.loads((out / "advice.json").read_text()) == summary


def test_a_csv_of_practical_places(tmp_path: Path) -> None:
    places = tmp_path / "places.csv"
    places.write_text("branch,chainage,name,cost\nZL12,1870,bridge Haarsteeg,2\nZL25,3000,farm road,1\n"
                      "Nriv_ZL_1_9820,1900,footbridge,3\n")
    done = rivercal("advise", "gauges", "dommel", "--params", "W4,W6,FA", "--window", WINDOW, "--candidates",
                    str(places), "--add", "1", "--workers", "1", "--json", "--out", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["candidates"] == {"source": str(places), "count": 3}
    assert len(summary["steps"]) == 1
    assert summary["steps"][0]["name"] in ("bridge Haarsteeg", "footbridge")  # the farm road sees neither crest
    assert summary["top"][-1]["name"] == "farm road"


@pytest.mark.parametrize(("content", "message"), [
    ("branch,chainage\nZL12,10\n", "line 1: the header must name the columns branch, chainage and name"),
    ("branch,chainage,name\nZL12,abc,x\n", "line 2: column 'chainage': 'abc' is not a number"),
    ("branch,chainage,name\nZL12,10,x\nZL13,10,y\n", "line 3: column 'branch': unknown branch 'ZL13'"),
    ("branch,chainage,name\nZL12,9000,x\n", "line 2: column 'chainage': chainage 9000 m is outside branch 'ZL12'"),
    ("branch,chainage,name,cost\nZL12,10,x,2\nZL12,20,y,\n", "line 3: column 'cost' is empty"),
    ("branch,chainage,name\nZL12,10,x\nZL12,1882,inside\n",
     "line 3: the places cannot be stations of case 'dommel': level station 'inside' at chainage 1882 m"),
])
def test_a_bad_csv_is_named_with_its_line(tmp_path: Path, content: str, message: str) -> None:
    places = tmp_path / "places.csv"
    places.write_text(content)
    done = rivercal("advise", "gauges", "dommel", "--params", "W4,FA", "--window", WINDOW, "--candidates",
                    str(places), "--out", str(tmp_path / "out"))
    assert done.returncode == 2
    assert str(places) in done.stderr and message in " ".join(done.stderr.split())


@pytest.mark.parametrize(("args", "message"), [
    (["--candidates", "pointz"], "--candidates 'pointz': neither points nor structures nor an existing CSV"),
    (["--kind", "flow"], "--kind"),
    (["--forecast", "9999"], "--forecast '9999': neither a station of the model"),
    (["--sigma", "h=-1"], "--sigma h=-1: σ must be positive"),
    (["--add", "0"], "--add"),
])
def test_bad_options_are_named(tmp_path: Path, args: list[str], message: str) -> None:
    done = rivercal("advise", "gauges", "dommel", "--params", "W4,FA", "--window", WINDOW, *args,
                    "--out", str(tmp_path / "out"))
    assert done.returncode == 2, done.stderr
    assert message in " ".join(done.stderr.split())
    assert "internal error" not in done.stderr


def test_a_model_that_cannot_add_places_says_so(tmp_path: Path) -> None:
    """EPA SWMM behind the contract has no VirtualStations capability: the command names it, before any run."""
    done = rivercal("advise", "gauges", "dommel-swmm", "--params", "W4,FA", "--window", WINDOW,
                    "--out", str(tmp_path / "out"))
    assert done.returncode == 2, done.stderr
    assert "lacks the optional capability VirtualStations" in " ".join(done.stderr.split())


def test_only_the_gauges_of_today_count_as_present(tmp_path: Path) -> None:
    """An imported model has a station at every observation point and structure; ``--gauges`` names the real ones."""
    done = rivercal("advise", "gauges", "dommel", "--gauges", "0028,0040,0029,0030", "--params", "FA", "--window",
                    WINDOW, "--candidates", "structures", "--add", "1", "--workers", "1", "--json", "--out",
                    str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["stations"] == ["0028", "0029", "0030", "0040"]
    table = (tmp_path / "out" / "candidates.csv").read_text()
    assert "ZL1-13409_up" in table and "ZL1-13409_down" in table  # the weir of 0031, no gauge now, is a candidate
    assert "ZL1-8052_up" not in table  # 0029's weir is measured
    refused = rivercal("advise", "gauges", "dommel", "--gauges", "0029,0099", "--params", "FA", "--window", WINDOW,
                       "--out", str(tmp_path / "out2"))
    assert refused.returncode == 2, refused.stderr
    assert "--gauges: '0099' is not a station of case 'dommel'" in " ".join(refused.stderr.split())
