"""The D-HYDRO test model "1D boundaries, c01 steady-state flow" (../shared/data), imported and run for its three days.

Four 2 km channels with a compound yz profile (lumped conveyance), Chézy 45 m^(1/2)/s, 100 m³/s from upstream
and 2.5 m downstream (a level, a ramped level, a Q(h) table). After three days the flow is steady, and the
levels along each channel must lie within 1 cm of the gradually-varied-flow ODE

    dh/dx = (S0 - Q² / K²) / (1 - Q² B / (g A³)),   K = C A √(A / P),

integrated upstream from the downstream level with scipy (:func:`rivercal.bench.models.steady_gvf_levels`, which
``rivercal bench models`` scores the model by too). A, P and B come from the yz polyline itself, computed by
dense sampling (independently of the engine's tables).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.bench.models import steady_gvf_levels
from rivercal.engine import Simulator
from rivercal.io.dhydro import import_dhydro
from rivercal.model import load_model
from tests.shared_data import shared_model


@pytest.mark.slow
def test_levels_after_three_days_follow_the_gradually_varied_flow_ode(tmp_path) -> None:
    mdu = shared_model("dhydro-1d-steady-state-flow", "Boundary.mdu")
    result = import_dhydro(mdu, tmp_path / "case")
    sim: Simulator = load_model(result.folder)
    out, _ = sim.simulate(snapshots=True)
    levels = out.levels.iloc[-1]
    c = sim.compiled
    assert out.balance.relative_error < 1e-6
    for branch in ("T1", "T2", "T3", "T4"):
        reference = steady_gvf_levels(100.0, 45.0, 0.5, 0.0, 2000.0, 2.5)
        points = [i for i, b in enumerate(c.hp_branch) if b == branch]
        chainage = c.hp_chainage[points]
        simulated = levels.iloc[points].to_numpy()
        error = np.abs(simulated - reference(chainage))
        assert error.max() < 0.01, f"{branch}: {error.max():.4f} m from the ODE at chainage {chainage[error.argmax()]}"
        # the steady discharge passes every link of the branch
    q = out.discharges.iloc[-1]
    assert np.allclose(q[[lab for lab in q.index if not lab.startswith(("weir", "culvert"))]], 100.0, atol=0.05)
    assert pd.Timestamp(out.levels.index[-1]) == sim.end


def test_a_model_folder_reached_through_a_link_imports_as_the_folder_itself(tmp_path) -> None:
    """A water board's models often lie behind a link (a mounted share, a 'current' link to a version):
    hydrolib-core opens the network file by its real path, which the confinement to the model folder took for a
    file outside it ('could not read it as a UGRID network'). Through a link the case is the same as without."""
    import tomllib

    mdu = shared_model("dhydro-1d-steady-state-flow", "Boundary.mdu")
    (tmp_path / "link").symlink_to(mdu.parent, target_is_directory=True)
    direct = import_dhydro(mdu, tmp_path / "direct")
    linked = import_dhydro(tmp_path / "link" / mdu.name, tmp_path / "linked")
    assert linked.summary == direct.summary
    assert tomllib.loads((tmp_path / "linked" / "case.toml").read_text(encoding="utf-8")) == tomllib.loads(
        (tmp_path / "direct" / "case.toml").read_text(encoding="utf-8"))
