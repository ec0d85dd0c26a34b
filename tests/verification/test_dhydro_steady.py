"""The D-HYDRO test model "1D boundaries, c01 steady-state flow" (../shared/data), imported and run for its three days.

Four 2 km channels with a compound yz profile (lumped conveyance), Chézy 45 m^(1/2)/s, 100 m³/s from upstream
and 2.5 m downstream (a level, a ramped level, a Q(h) table). After three days the flow is steady, and the
levels along each channel must lie within 1 cm of the gradually-varied-flow ODE

    dh/dx = (S0 - Q² / K²) / (1 - Q² B / (g A³)),   K = C A √(A / P),

integrated upstream from the downstream level with scipy. A, P and B come from the yz polyline itself,
computed here by dense sampling (independently of the engine's tables).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

from rivercal.engine import Simulator
from rivercal.io.dhydro import import_dhydro
from rivercal.model import load_model
from tests.shared_data import shared_model

G = 9.81
Y = np.array([0.0, 0.001, 5.0, 10.0, 20.0, 30.0, 40.0, 45.0, 49.999, 50.0])
Z = np.array([3.0, 2.5, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 2.5, 3.0])


def _geometry(depth: float) -> tuple[float, float, float]:
    """Flow area (m²), wetted perimeter (m) and top width (m) of the yz profile at a depth above its lowest point.

    The bed between the survey points is linear; above the end points the walls are vertical.
    """
    y = np.linspace(Y[0], Y[-1], 200_001)
    z = np.interp(y, Y, Z)
    wet = np.clip(depth - z, 0.0, None)
    area = float(np.sum(0.5 * (wet[1:] + wet[:-1]) * np.diff(y)))
    width = float(np.sum(np.diff(y)[(wet[1:] > 0) | (wet[:-1] > 0)]))
    # wetted perimeter: the length of bed under water, piece by piece, plus walls above the ends
    per = 0.0
    for k in range(Y.size - 1):
        lo, hi = sorted((Z[k], Z[k + 1]))
        if depth <= lo:
            continue
        frac = 1.0 if depth >= hi or hi == lo else (depth - lo) / (hi - lo)
        per += frac * np.hypot(Y[k + 1] - Y[k], Z[k + 1] - Z[k])
    per += max(depth - Z[0], 0.0) + max(depth - Z[-1], 0.0)
    return area, per, width


def _gvf(q: float, chezy: float, bed_up: float, bed_down: float, length: float, level_down: float):
    """Levels (m AD) along the channel, from the ODE integrated upstream from ``level_down``."""
    slope = (bed_up - bed_down) / length

    def rhs(x, h):  # x: chainage from upstream, h: depth above the local bed
        a, p, b = _geometry(h[0])
        k = chezy * a * np.sqrt(a / p)
        return [(slope - q * q / (k * k)) / (1.0 - q * q * b / (G * a**3))]

    sol = solve_ivp(rhs, (length, 0.0), [level_down - bed_down], rtol=1e-9, atol=1e-10, dense_output=True)
    return lambda x: sol.sol(x)[0] + bed_up + (bed_down - bed_up) * x / length


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
        reference = _gvf(100.0, 45.0, 0.5, 0.0, 2000.0, 2.5)
        points = [i for i, b in enumerate(c.hp_branch) if b == branch]
        chainage = c.hp_chainage[points]
        simulated = levels.iloc[points].to_numpy()
        error = np.abs(simulated - reference(chainage))
        assert error.max() < 0.01, f"{branch}: {error.max():.4f} m from the ODE at chainage {chainage[error.argmax()]}"
        # the steady discharge passes every link of the branch
    q = out.discharges.iloc[-1]
    assert np.allclose(q[[lab for lab in q.index if not lab.startswith(("weir", "culvert"))]], 100.0, atol=0.05)
    assert pd.Timestamp(out.levels.index[-1]) == sim.end
