"""The real D-HYDRO models of ../shared/data, imported and run: mass balance, a sewer network.

(Dellen against D-HYDRO's own levels, and its water balance over the week: test_dhydro_dellen_fidelity.py.)
- Korte Woerden (an urban sewer network): every object accounted for, and with a constant inflow of 1 l/s on
  each of its 72 realtime laterals it runs its two hours without diverging, and its schematic is drawn.
- Every other imported model closes its water balance to 1e-6 with finite levels.
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.io.dhydro import ImportOptions, import_dhydro
from rivercal.model import load_model
from rivercal.report.figures import plot_network
from tests.dhydro_models import write_model
from tests.shared_data import shared_model

#: The documented constant inflow of each realtime lateral of Korte Woerden, m³/s (1 l/s per sewer area).
KORTE_WOERDEN_INFLOW = 0.001


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


@pytest.mark.parametrize("model", ["steady", "korte-woerden", "hydrolib-built"])
def test_imported_models_close_their_water_balance(model, tmp_path) -> None:
    options = ImportOptions(realtime_lateral=KORTE_WOERDEN_INFLOW)
    if model == "steady":
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


def test_a_sobek3_model_exported_to_dflowfm_comes_back_as_the_same_case(tmp_path) -> None:
    """The SOBEK 3 compound channel (LGPL, ../shared/data) has what D-Flow FM files must carry back: floodplain
    sections, a summer dike on each of its 7 profiles, a Chézy water-level table (in a Manning group) at 7
    chainages, initial levels along its branch. Imported from SOBEK 3, written as D-Flow FM files and imported
    from those, it is the same case — friction, profiles, branches, initial state — with the same levels at every
    calculation point over its 38 days."""
    import tomllib

    from rivercal.io.dhydro import export_dhydro
    from rivercal.io.sobek3 import import_sobek3

    md1d = shared_model("sobek3-compound", "test_compound.dsproj_data", "Flow1D_output", "dflow1d", "Flow1D.md1d")
    first = import_sobek3(md1d, tmp_path / "case")
    exported = export_dhydro(load_model(first.folder).case, tmp_path / "model")
    second = import_dhydro(exported.mdu, tmp_path / "again")
    a = tomllib.loads((first.folder / "case.toml").read_text(encoding="utf-8"))
    b = tomllib.loads((second.folder / "case.toml").read_text(encoding="utf-8"))
    assert sum("summer_dike" in p for p in a["profiles"]) == 7
    assert any(e.get("function") == "waterlevel" for g in a["friction_groups"] for e in g.get("branches", []))
    assert all("initial_levels" in br for br in a["branches"])
    for key in ("friction_groups", "profiles", "nodes", "branches", "boundaries", "initial"):
        assert b[key] == a[key], key
    assert b["engine"]["dt"] == a["engine"]["dt"]  # the time step travels in rivercal.ini
    out_a, _ = load_model(first.folder).simulate(snapshots=True)
    out_b, _ = load_model(second.folder).simulate(snapshots=True)
    assert list(out_a.levels.columns) == list(out_b.levels.columns)
    assert np.abs(out_a.levels.to_numpy() - out_b.levels.loc[out_a.levels.index].to_numpy()).max() <= 1e-6
