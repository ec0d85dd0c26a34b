"""``rivercal import dhydro`` and ``rivercal export dhydro`` as a user runs them, and the round trip of dommel."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rivercal.model import load_model
from tests.cli import rivercal
from tests.dhydro_models import write_model
from tests.shared_data import shared_model


def test_import_prints_the_summary_as_json(tmp_path: Path) -> None:
    mdu = shared_model("dhydro-dellen", "dflowfm", "Flow1D.mdu")
    folder = mdu.parents[1]
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"), "--realtime",
                   str(folder / "rr_to_flow.nc"), "--realtime", str(folder / "rtc_to_flow.nc"), "--json")
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert set(summary) == {"branches", "points", "profiles", "structures", "boundaries", "laterals", "stations",
                            "approximated", "refused"}
    assert (summary["branches"], summary["points"], summary["laterals"]) == (171, 653, 143)
    assert summary["structures"] == {"weir": 19, "culvert": 147, "pump": 2, "bridge": 7}
    assert summary["refused"] == 0
    assert (tmp_path / "case" / "import.md").is_file()


def test_a_refusal_is_an_error_naming_the_objects_and_the_way_out(tmp_path: Path) -> None:
    mdu = write_model(tmp_path / "model")
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"))
    assert run.returncode == 2
    assert "lateral 'lat_node'" in run.stderr and "--allow-partial" in run.stderr and "import.md" in run.stderr
    assert "no case was written" in run.stderr
    # only the report: no case folder that would run without the refused objects
    assert sorted(p.name for p in (tmp_path / "case").iterdir()) == ["import.md"]
    run = rivercal("import", "dhydro", str(mdu), "--out", str(tmp_path / "case"), "--allow-partial")
    assert run.returncode == 0, run.stderr
    assert "refused" in run.stdout


def test_a_file_that_is_not_a_model_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "model.mdu"
    bad.write_text("[geometry]\nNetFile = missing_net.nc\n", encoding="utf-8")
    run = rivercal("import", "dhydro", str(bad), "--out", str(tmp_path / "case"))
    assert run.returncode == 2
    assert "model.mdu" in run.stderr


@pytest.mark.slow
def test_import_of_the_export_of_dommel_reproduces_its_series(tmp_path: Path) -> None:
    run = rivercal("export", "dhydro", "dommel", "--out", str(tmp_path / "model"), "--json")
    assert run.returncode == 0, run.stderr
    mdu = json.loads(run.stdout)["mdu"]
    run = rivercal("import", "dhydro", mdu, "--out", str(tmp_path / "case"), "--json")
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["refused"] == 0
    original, again = load_model("dommel"), load_model(tmp_path / "case")
    a, _ = original.simulate()
    b, _ = again.simulate()
    b_series = b.series.loc[a.series.index]  # the export starts the spin-up earlier
    compared = 0
    for st in original.case.network.stations:
        for q in st.quantities or ["h_up", "h_down"]:
            np.testing.assert_allclose(b_series[f"{st.structure}.{q}"].to_numpy(), a.series[f"{st.id}.{q}"].to_numpy(),
                                       rtol=0, atol=1e-9)
            compared += 1
    assert compared == 11
