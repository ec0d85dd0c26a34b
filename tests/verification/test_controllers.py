"""Controlled weirs: a PID holding a basin's level against the ODE integrated by scipy, limits, mass balance.

Reference
---------
A basin of plan area A (m²) fed a constant Q_in (m³/s) drains over a weir of width W in free flow,
Q = c (2/3) √((2/3) g) W (h - z_s)^1.5 (thesis Eq. 3-4). A PID sets the crest from the basin level,
z_s = b + k_p e + k_i ∫e dt with e = h_set - h, so that

    A dh/dt = Q_in - Q(h - z_s),    dI/dt = h_set(t) - h,

which :func:`scipy.integrate.solve_ivp` integrates (Radau, tolerance 1e-10) from the equilibrium at the first
setpoint. The engine's controller acts once per step (zero-order hold); with Δt = 30 s against a closed-loop
period of hours the two agree to well within 1 % of the setpoint step.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rivercal.engine.kernels.control import S_INTEGRAL
from tests.verification._support import START, case_dict, simulator

G = 9.81
AREA = 20_000.0  # m², the basin
WIDTH = 2.0  # m, weir crest and outlet channel
Q_IN = 1.0  # m³/s
SET0, SET1 = 2.0, 2.2  # m AD, the setpoint before and after the step
STEP_AT = 6.0  # h
KP, KI = 1.0, 1.0 / 3600.0  # m/m, 1/s
CW = (2.0 / 3.0) * np.sqrt((2.0 / 3.0) * G) * WIDTH  # free weir flow per m^1.5


def _case(controller: dict, *, hours: float, dt: float, out: float, q_in: float | dict = Q_IN) -> dict:
    data = case_dict(
        hours=hours,
        engine={"dt": dt, "output_interval": out},
        initial={"level": SET0, "depth": 0.1, "spinup": 120.0},
        profiles=[{"id": "ditch", "type": "rectangular", "width": WIDTH}],
        nodes=[{"id": "basin", "storage_area": AREA}, {"id": "out"}],
        branches=[{"id": "outlet", "from_node": "basin", "to_node": "out", "length": 200.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "ditch", "bed_level": 0.0},
                                      {"chainage": 200.0, "profile": "ditch", "bed_level": -0.5}]}],
        boundaries=[{"id": "in", "node": "basin", "type": "discharge", **(
            {"value": q_in} if isinstance(q_in, float) else q_in)},
                    {"id": "sea", "node": "out", "type": "level", "value": -0.2}],
        weirs=[{"id": "W", "branch": "outlet", "chainage": 5.0, "crest_level": 1.5, "crest_width": WIDTH}],
    )
    data["controllers"] = [{"id": "C", "weir": "W", **controller}]
    return data


def _basin_area(sim) -> float:
    # the basin point also stores half of the weir's 10 m segment of channel and the minimum area (as the pump test)
    return AREA + 0.5 * sim.settings.structure_length * WIDTH + sim.settings.min_storage_area


def _pid_step_errors(tmp_path: Path, dt: float) -> tuple[float, float, float, np.ndarray, float]:
    """Largest level and crest differences (m) between engine and ODE, the crest excursion (m), the levels, and
    the balance residual relative to the throughput."""
    table = {"times": [START.isoformat(), (START + np.timedelta64(int(STEP_AT * 3600), "s")).isoformat()],
             "values": [SET0, SET1], "interpolation": "block"}
    data = _case({"type": "pid", "measure": "W.h_up", "setpoint_table": table, "kp": KP, "ki": KI,
                  "min": 0.5, "max": 3.0}, hours=36.0, dt=dt, out=600.0)
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    h = result.levels["node:basin"].to_numpy()
    crest = result.series["W.crest"].to_numpy()
    t = (result.series.index - START).total_seconds().to_numpy()

    area = _basin_area(sim)
    bias = 1.5  # the weir's crest_level
    c_eq = SET0 - (Q_IN / CW) ** (2.0 / 3.0)

    def rhs(time, y):
        level, integral = y
        e = (SET1 if time >= STEP_AT * 3600.0 else SET0) - level
        c = bias + KP * e + KI * integral
        head = max(level - c, 0.0)
        return [(Q_IN - CW * head**1.5) / area, e]

    ode = solve_ivp(rhs, (0.0, t[-1]), [SET0, (c_eq - bias) / KI], method="Radau", t_eval=t, rtol=1e-10,
                    atol=1e-10, max_step=60.0)
    assert ode.success
    c_ode = bias + KP * (np.where(t >= STEP_AT * 3600.0, SET1, SET0) - ode.y[0]) + KI * ode.y[1]
    assert abs(h[0] - SET0) < 1e-3 and abs(crest[0] - c_eq) < 1e-3  # the spin-up settled the loop
    return (float(np.max(np.abs(h - ode.y[0]))), float(np.max(np.abs(crest[1:] - c_ode[1:]))), float(np.ptp(c_ode)),
            h, abs(result.balance.residual) / result.balance.throughput)


def test_pid_step_response_matches_the_ode_within_one_percent(tmp_path: Path) -> None:
    level_err, crest_err, excursion, h, balance = _pid_step_errors(tmp_path, 30.0)
    step = SET1 - SET0
    assert (h.max() - SET0) > 0.9 * step  # the step did happen: the response is not trivial
    assert level_err <= 0.01 * step, level_err  # measured: 0.48 % (0.96 mm of the 0.2 m step)
    assert crest_err <= 0.01 * excursion, (crest_err, excursion)  # measured: 0.66 %
    assert balance <= 1e-6
    # the difference is the controller's one action per step: it halves with the step (first order)
    level_err60, _, _, _, _ = _pid_step_errors(tmp_path, 60.0)
    assert 1.7 <= level_err60 / level_err <= 2.3, (level_err60, level_err)


@pytest.mark.parametrize("speed", [0.05, 0.01])  # m/min
def test_crest_speed_and_output_limits_hold_exactly(tmp_path: Path, speed: float) -> None:
    # an aggressive PID against an inflow that jumps from 0.2 to 3 m³/s and then stops: the crest runs into both
    # limits (lowered to pass the flood, raised to hold the falling level)
    hours = (0.0, 2.0, 2.02, 6.0, 6.02, 12.0)
    flows = (0.2, 0.2, 3.0, 3.0, 0.0, 0.0)
    (tmp_path / "q.csv").write_text("time,q\n" + "".join(
        f"{(START + np.timedelta64(int(h * 3600), 's')).strftime('%Y-%m-%dT%H:%M:%SZ')},{v}\n"
        for h, v in zip(hours, flows, strict=True)))
    lo, hi = 1.6, 1.95
    data = _case({"type": "pid", "measure": "W.h_up", "setpoint": SET0, "kp": 20.0, "ki": 0.01, "kd": 30.0,
                  "min": lo, "max": hi, "max_speed": speed},
                 hours=12.0, dt=60.0, out=60.0, q_in={"series": {"file": "q.csv", "column": "q"}})
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate()
    crest = result.series["W.crest"].to_numpy()
    assert crest.min() >= lo and crest.max() <= hi
    assert crest.min() == lo and crest.max() == hi  # both limits reached, exactly
    moves = np.abs(np.diff(crest))
    limit = speed / 60.0 * sim.dt
    assert moves.max() <= limit * (1 + 1e-12)
    assert moves.max() >= limit * (1 - 1e-12)  # and the speed limit was active
    assert abs(result.balance.residual) <= 1e-6 * result.balance.throughput


def test_interval_controller_steps_at_its_interval_outside_the_dead_band(tmp_path: Path) -> None:
    data = _case({"type": "interval", "measure": "W.h_up", "setpoint": SET0, "dead_band": 0.04, "step": 0.02,
                  "interval": 600.0, "min": 1.0, "max": 2.5}, hours=24.0, dt=60.0, out=60.0)
    data["initial"]["spinup"] = 0.0
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    crest = result.series["W.crest"].to_numpy()
    level = result.levels["node:basin"].to_numpy()  # row n: the level at the start of step n
    change = np.diff(crest)  # change[n]: the crest move decided at the start of step n
    decisions = np.arange(9, change.size, 10)  # every 600 s: the 10th, 20th ... step
    assert np.all(change[np.setdiff1d(np.arange(change.size), decisions)] == 0.0)  # nothing moves in between
    lowered, raised = change[decisions] < 0, change[decisions] > 0
    assert raised.sum() >= 3  # the level starts at 2.0 m over a 1.5 m crest: it falls below the band at first
    assert np.allclose(np.abs(change[decisions][lowered | raised]), 0.02, rtol=0, atol=1e-12)  # whole steps
    z = level[decisions]
    assert np.all(z[lowered] > SET0 + 0.02) and np.all(z[raised] < SET0 - 0.02)
    assert np.all(np.abs(z[~(lowered | raised)] - SET0) <= 0.02)  # within the dead band: no action
    assert abs(level[-1] - SET0) <= 0.03  # and it ends near its setpoint
    assert abs(result.balance.residual) <= 1e-6 * result.balance.throughput


def test_relation_controller_sets_the_tabulated_crest_of_the_measured_discharge(tmp_path: Path) -> None:
    # the crest follows a table of the weir's own discharge (m³/s): each step's crest is the table's value at the
    # discharge at the start of that step, linear between its points and constant beyond them
    hours = (0.0, 3.0, 9.0, 12.0)
    flows = (0.2, 0.2, 3.0, 0.5)
    (tmp_path / "q.csv").write_text("time,q\n" + "".join(
        f"{(START + np.timedelta64(int(h * 3600), 's')).strftime('%Y-%m-%dT%H:%M:%SZ')},{v}\n"
        for h, v in zip(hours, flows, strict=True)))
    x, crest_table = [0.5, 1.0, 2.5], [1.8, 1.7, 1.3]
    data = _case({"type": "relation", "measure": "W.Q", "table": {"x": x, "crest": crest_table},
                  "min": 1.0, "max": 2.5}, hours=12.0, dt=60.0, out=60.0,
                 q_in={"series": {"file": "q.csv", "column": "q"}})
    sim = simulator(data, tmp_path)
    result, _ = sim.simulate(snapshots=True)
    q = result.discharges.iloc[:, sim.compiled.structure_link["W"]].to_numpy()
    crest = result.series["W.crest"].to_numpy()
    expected = np.interp(q[:-1], x, crest_table)  # the step starting at row n sets the crest of row n + 1
    assert np.max(np.abs(crest[1:] - expected)) < 1e-12
    assert q.min() < x[0] and q.max() > x[-1]  # both flat ends and the slopes were used
    assert abs(result.balance.residual) <= 1e-6 * result.balance.throughput


def test_the_integral_is_held_while_the_crest_sits_at_its_limit(tmp_path: Path) -> None:
    # a setpoint the weir cannot hold (the level stays above it even with the crest at its minimum): the crest
    # sits at min, and with conditional integration the integral stops growing there instead of winding up
    data = _case({"type": "pid", "measure": "W.h_up", "setpoint": 1.6, "kp": 1.0, "ki": 1e-3,
                  "min": 1.5, "max": 2.5}, hours=48.0, dt=60.0, out=3600.0)
    data["initial"]["spinup"] = 0.0
    sim = simulator(data, tmp_path)
    end = sim.start + np.timedelta64(12, "h")
    first, state = sim.simulate(end=end)
    assert np.all(first.series["W.crest"].to_numpy()[-3:] == 1.5)  # at its limit
    held = state.ctl[0, S_INTEGRAL]
    later, after = sim.simulate(start=end, state=state)
    assert np.all(later.series["W.crest"].to_numpy() == 1.5)
    assert after.ctl[0, S_INTEGRAL] == held  # not one more step of error added in 36 h
    # now the manager raises the setpoint above the level: the crest leaves its limit at once
    again, _ = sim.simulate({"control:C.setpoint": 2.2}, start=end, state=state)
    assert again.series["W.crest"].iloc[1] > 1.5
