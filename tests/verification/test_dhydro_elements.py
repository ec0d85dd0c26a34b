"""The hydraulic elements a D-HYDRO model brings, each against an independent reference.

Channels (uniform flow: the normal depth solves Q = K(h) √S0, K computed here from the geometry):

- a segmented yz profile: K = k_s Σ_i A_i R_i^(2/3) over the pieces between survey points;
- a zw profile with a main channel and a floodplain of other friction groups: K = Σ_s k_s A_s R_s^(2/3);
- a circular pipe running part full (Manning);
- White-Colebrook friction: K = A C √R with C = 18 log10(12 R / k_n).

Structures between two level boundaries (a steady discharge; the formulas written out here):

- orifice: free gate flow Q = μ W a √(2g(h1 - z_s - μ a)), submerged Q = μ W a √(2g(h1 - h2)), and weir flow
  under a raised gate; the discharge limit;
- universal weir: a V-shaped crest, Q = c_e (2/3) √((2/3) g) ∫ (h1 - z(y))^(3/2) dy (scipy quad);
- culvert with two inverts (a siphon) running full: Q = A √(2g Δh / ξ), ξ = ξ_in + ξ_bend + 2gL/(C²R) + ξ_out;
  and the exit loss ξ_out (1 - A/A_2)² of the expansion option;
- bridge (an open rectangular opening, submerged): the same law on the opening's wetted area;
- a weir whose crest follows a series: after each step the level is that of the weir law with the new crest.

And the interpolated placement of cross-sections keeps a lake at rest.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from tests.verification._support import START, case_dict, max_level_change, simulator, write_series

G = 9.81


# -- uniform flow --------------------------------------------------------------------------------------


def _uniform_case(profile: dict, q: float, slope: float, depth: float, *, friction_groups=None,
                  friction=None, length: float = 4000.0) -> dict:
    data = case_dict(
        hours=36.0, engine={"dt": 120.0}, initial={"depth": depth}, friction=friction,
        profiles=[profile], nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": length, "dx": 100.0,
                   "cross_sections": [{"chainage": 0.0, "profile": profile["id"], "bed_level": slope * length},
                                      {"chainage": length, "profile": profile["id"], "bed_level": 0.0}]}],
        boundaries=[{"id": "Qin", "node": "up", "type": "discharge", "value": q},
                    {"id": "hout", "node": "down", "type": "level", "value": depth}],
        stations=[{"id": "mid", "branch": "B", "chainage": length / 2, "quantities": ["h", "Q"]}],
    )
    if friction_groups:
        data["friction_groups"] = friction_groups
    return data


def _normal_depth(conveyance, q: float, slope: float, top: float) -> float:
    return brentq(lambda h: conveyance(h) * math.sqrt(slope) - q, 1e-3, top, xtol=1e-12)


def _run_uniform(tmp_path: Path, data: dict, slope: float, length: float = 4000.0) -> float:
    sim = simulator(data, tmp_path)
    out, _ = sim.simulate(snapshots=True)
    assert max_level_change(out.levels) < 1e-5
    return float(out.series["mid.h"].iloc[-1] - slope * length / 2)


def _pieces_yz(y, z, depth):
    """Wetted area and bed length of each piece of a yz profile at a depth (the bed linear between points)."""
    out = []
    for k in range(len(y) - 1):
        y0, z0, y1, z1 = y[k], z[k], y[k + 1], z[k + 1]
        lo, hi = sorted((z0, z1))
        if depth <= lo:
            out.append((0.0, 0.0))
            continue
        length = math.hypot(y1 - y0, z1 - z0)
        if depth >= hi:
            out.append(((y1 - y0) * (depth - 0.5 * (z0 + z1)), length))
        else:
            frac = (depth - lo) / (hi - lo)
            out.append((0.5 * frac * (y1 - y0) * (depth - lo), frac * length))
    return out


def test_segmented_yz_profile_has_the_normal_depth_of_its_piecewise_conveyance(tmp_path: Path) -> None:
    y = [0.0, 10.0, 14.0, 20.0, 26.0, 30.0, 40.0]
    z = [3.0, 2.0, 1.0, 0.0, 1.0, 2.0, 3.0]
    ks, q, slope = 25.0, 9.0, 3e-4

    def conveyance(h):
        return ks * sum(a * (a / p) ** (2.0 / 3.0) for a, p in _pieces_yz(y, z, h) if a > 0)

    hn = _normal_depth(conveyance, q, slope, 3.0)
    assert 1.0 < hn < 2.0  # the banks are wet: the pieces matter
    data = _uniform_case({"id": "yz", "type": "yz", "y": y, "z": z}, q, slope, hn,
                         friction={"type": "strickler", "value": ks})
    assert _run_uniform(tmp_path, data, slope) == pytest.approx(hn, abs=2e-3)


def test_zw_sections_with_their_own_friction_groups(tmp_path: Path) -> None:
    heights, widths = [0.0, 2.0, 2.0001, 4.0], [10.0, 10.0, 60.0, 60.0]
    k_main, k_flood, q, slope = 35.0, 15.0, 50.0, 2e-4

    def conveyance(h):  # main channel 10 m wide (walls), floodplain 50 m from 2 m up (bottom and outer wall)
        a_main = 10.0 * h
        p_main = 10.0 + 2.0 * min(h, 2.0)
        k = k_main * a_main * (a_main / p_main) ** (2.0 / 3.0)
        if h > 2.0001:
            a_fp = 50.0 * (h - 2.0001) + 25.0 * 1e-4
            p_fp = 50.0 + 2.0 * (h - 2.0001)
            k += k_flood * a_fp * (a_fp / p_fp) ** (2.0 / 3.0)
        return k

    hn = _normal_depth(conveyance, q, slope, 4.0)
    assert 2.1 < hn < 4.0  # the floodplain carries part of the flow
    profile = {"id": "river", "type": "zw", "heights": heights, "flow_widths": widths,
               "section_widths": [10.0, 50.0], "friction": ["main", "flood"]}
    groups = [{"id": "main", "type": "strickler", "value": k_main}, {"id": "flood", "type": "strickler",
                                                                     "value": k_flood}]
    data = _uniform_case(profile, q, slope, hn, friction_groups=groups)
    assert _run_uniform(tmp_path, data, slope) == pytest.approx(hn, abs=5e-3)


def test_circular_pipe_part_full(tmp_path: Path) -> None:
    d, n, q, slope = 1.2, 0.013, 0.6, 1e-3

    def conveyance(h):
        theta = 2.0 * math.acos(1.0 - 2.0 * h / d)
        a = d * d / 8.0 * (theta - math.sin(theta))
        return a * (a / (0.5 * d * theta)) ** (2.0 / 3.0) / n

    hn = _normal_depth(conveyance, q, slope, 0.99 * d)
    data = _uniform_case({"id": "pipe", "type": "circular", "diameter": d}, q, slope, hn,
                         friction={"type": "manning", "value": n}, length=1000.0)
    assert _run_uniform(tmp_path, data, slope, 1000.0) == pytest.approx(hn, abs=2e-3)


def test_white_colebrook_friction(tmp_path: Path) -> None:
    b, k_n, q, slope = 6.0, 0.05, 10.0, 2e-4

    def conveyance(h):
        a, r = b * h, b * h / (b + 2 * h)
        return a * 18.0 * math.log10(12.0 * r / k_n) * math.sqrt(r)

    hn = _normal_depth(conveyance, q, slope, 10.0)
    data = _uniform_case({"id": "rect", "type": "rectangular", "width": b}, q, slope, hn,
                         friction={"type": "white-colebrook", "value": k_n})
    assert _run_uniform(tmp_path, data, slope) == pytest.approx(hn, abs=2e-3)


# -- structures between two level boundaries ---------------------------------------------------------------


def _structure_case(table: str, item: dict, h1: float, h2: float, *, profiles=None, width: float = 40.0) -> dict:
    """A 20 m branch ``up`` → ``down`` whose one link carries the structure, both ends held at levels h1, h2."""
    data = case_dict(
        hours=2.0, engine={"dt": 30.0, "max_iterations": 10, "tolerance": 1e-7}, initial={"level": h1, "depth": 0.0},
        profiles=[{"id": "wide", "type": "rectangular", "width": width}, *(profiles or [])],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": 20.0, "points": [0.0, 20.0],
                   "cross_sections": [{"chainage": 0.0, "profile": "wide", "bed_level": 0.0}]}],
        boundaries=[{"id": "hu", "node": "up", "type": "level", "value": h1},
                    {"id": "hd", "node": "down", "type": "level", "value": h2}],
        stations=[{"id": "S", "structure": item["id"], "quantities": ["h_up", "h_down", "Q"]}],
    )
    data[table] = [{"branch": "B", "chainage": 10.0, **item}]
    return data


def _steady_q(tmp_path: Path, data: dict) -> float:
    out, _ = simulator(data, tmp_path).simulate()
    q = out.series["S.Q"]
    assert abs(q.iloc[-1] - q.iloc[-2]) < 1e-9 * max(1.0, abs(q.iloc[-1]))
    return float(q.iloc[-1])


ORIFICE = {"id": "O", "crest_level": 1.0, "crest_width": 3.0, "gate_lower_edge_level": 1.5,
           "discharge_coefficient": 0.63}


@pytest.mark.parametrize(("h1", "h2", "regime"), [(3.0, 1.2, "free gate"), (3.0, 2.6, "submerged gate"),
                                                  (1.6, 1.1, "free weir")])
def test_orifice_discharge(tmp_path: Path, h1: float, h2: float, regime: str) -> None:
    mu, w, a, zs = 0.63, 3.0, 0.5, 1.0
    if regime == "free gate":
        expected = mu * w * a * math.sqrt(2 * G * (h1 - zs - mu * a))
    elif regime == "submerged gate":
        expected = mu * w * a * math.sqrt(2 * G * (h1 - h2))
    else:
        expected = mu * w * (2.0 / 3.0) * math.sqrt((2.0 / 3.0) * G) * (h1 - zs) ** 1.5
    q = _steady_q(tmp_path, _structure_case("orifices", ORIFICE, h1, h2))
    assert q == pytest.approx(expected, rel=1e-6)


def test_orifice_discharge_limit(tmp_path: Path) -> None:
    q = _steady_q(tmp_path, _structure_case("orifices", {**ORIFICE, "max_flow_positive": 1.5}, 3.0, 1.2))
    assert q == pytest.approx(1.5, rel=1e-9)


def test_universal_weir_with_a_v_shaped_crest(tmp_path: Path) -> None:
    ce, crest, h1 = 0.9, 1.0, 1.8
    y, z = [0.0, 4.0, 8.0], [1.0, 0.0, 1.0]  # a V: 1 m deep over 4 m each side

    def depth(yy):
        return max(h1 - crest - np.interp(yy, y, z), 0.0)

    # free flow over every strip: each strip passes ce (2/3) sqrt(2/3 g) H^1.5 per metre
    expected = ce * (2.0 / 3.0) * math.sqrt((2.0 / 3.0) * G) * quad(lambda yy: depth(yy) ** 1.5, 0.0, 8.0,
                                                                    points=[4.0])[0]
    item = {"id": "U", "y": y, "z": z, "crest_level": crest, "discharge_coefficient": ce}
    q = _steady_q(tmp_path, _structure_case("universal_weirs", item, h1, 0.5))
    # the sloping sides are taken in 8 strips each: within 0.5 % of the integral
    assert q == pytest.approx(expected, rel=5e-3)


def test_siphon_running_full(tmp_path: Path) -> None:
    d, length, ks, xin, xbend, xout = 0.8, 30.0, 70.0, 0.5, 0.4, 1.0
    h1, h2 = 2.0, 1.7
    a = math.pi * d * d / 4.0
    r = d / 4.0
    c2r = ks * ks * r ** (4.0 / 3.0)
    expected = a * math.sqrt(2 * G * (h1 - h2) / (xin + xbend + xout + 2 * G * length / c2r))
    item = {"id": "C", "shape": "circular", "diameter": d, "invert_level": -1.0, "invert_level_end": -1.2,
            "length": length, "inlet_loss": xin, "outlet_loss": xout, "bend_loss": xbend,
            "friction": {"type": "strickler", "value": ks}}
    q = _steady_q(tmp_path, _structure_case("culverts", item, h1, h2))
    assert q == pytest.approx(expected, rel=1e-6)


def test_culvert_exit_loss_with_the_downstream_expansion(tmp_path: Path) -> None:
    w, hgt, length, n, xin, xout = 1.0, 1.0, 10.0, 0.013, 0.5, 1.0
    h1, h2, channel = 2.0, 1.9, 40.0
    a = w * hgt
    a2 = channel * h2  # the channel's flow area downstream (rectangular, bed at 0)
    r = a / (2 * (w + hgt))
    c2r = r ** (4.0 / 3.0) / (n * n)
    xi = xin + xout * (1.0 - a / a2) ** 2 + 2 * G * length / c2r
    expected = a * math.sqrt(2 * G * (h1 - h2) / xi)
    item = {"id": "C", "shape": "rectangular", "width": w, "height": hgt, "invert_level": 0.0, "length": length,
            "inlet_loss": xin, "outlet_loss": xout, "outlet_expansion": True,
            "friction": {"type": "manning", "value": n}}
    q = _steady_q(tmp_path, _structure_case("culverts", item, h1, h2, width=channel))
    assert q == pytest.approx(expected, rel=1e-6)


def test_bridge_opening_submerged(tmp_path: Path) -> None:
    w, length, ks, xin, xout = 5.0, 8.0, 40.0, 0.3, 0.8
    h1, h2, bed, channel = 2.0, 1.95, 0.2, 40.0
    depth = h2 - bed
    a = w * depth
    r = a / (w + 2 * depth)
    a2 = channel * h2
    xi = xin + xout * (1.0 - a / a2) ** 2 + 2 * G * length / (ks * ks * r ** (4.0 / 3.0))
    expected = a * math.sqrt(2 * G * (h1 - h2) / xi)
    item = {"id": "Br", "profile": "opening", "bed_level": bed, "length": length, "inlet_loss": xin,
            "outlet_loss": xout, "friction": {"type": "strickler", "value": ks}}
    profiles = [{"id": "opening", "type": "rectangular", "width": w, "height": 3.0}]
    q = _steady_q(tmp_path, _structure_case("bridges", item, h1, h2, profiles=profiles, width=channel))
    assert q == pytest.approx(expected, rel=1e-3)  # the opening's area comes from its table (5 mm cells)


def test_a_weir_crest_that_follows_a_series(tmp_path: Path) -> None:
    """A steady inflow over a weir whose crest is raised by 0.3 m after 12 h: the upstream level follows
    h1 = z_s + (Q / (c W (2/3) √((2/3) g)))^(2/3) before and after."""
    q, w, c = 2.0, 4.0, 1.0
    head = (q / (c * w * (2.0 / 3.0) * math.sqrt((2.0 / 3.0) * G))) ** (2.0 / 3.0)
    times = pd.date_range(START, START + pd.Timedelta("24h"), freq="1h")
    crest = np.where(times < START + pd.Timedelta("12h"), 1.0, 1.3)
    data = case_dict(
        hours=24.0, engine={"dt": 60.0, "max_iterations": 10, "tolerance": 1e-7}, initial={"level": 1.0, "depth": 0.0},
        profiles=[{"id": "wide", "type": "rectangular", "width": 30.0}],
        nodes=[{"id": "up"}, {"id": "down"}],
        branches=[{"id": "B", "from_node": "up", "to_node": "down", "length": 200.0, "points": [0.0, 100.0, 200.0],
                   "cross_sections": [{"chainage": 0.0, "profile": "wide", "bed_level": 0.0}]}],
        boundaries=[{"id": "Qin", "node": "up", "type": "discharge", "value": q},
                    {"id": "hd", "node": "down", "type": "level", "value": 0.5}],
        weirs=[{"id": "W", "branch": "B", "chainage": 150.0, "crest_level": 1.0, "crest_width": w,
                "crest_series": {"file": "crest.csv", "column": "W"}}],
        stations=[{"id": "S", "structure": "W", "quantities": ["h_up", "Q"]}],
    )
    write_series(tmp_path, "crest.csv", times, W=crest)
    out, _ = simulator(data, tmp_path).simulate()
    assert out.series["S.h_up"].loc[START + pd.Timedelta("11h")] == pytest.approx(1.0 + head, abs=2e-3)
    assert out.series["S.h_up"].iloc[-1] == pytest.approx(1.3 + head, abs=2e-3)
    assert out.series["S.Q"].iloc[-1] == pytest.approx(q, rel=1e-3)


# -- interpolated cross-sections -------------------------------------------------------------------------


def test_interpolated_cross_sections_keep_a_lake_at_rest(tmp_path: Path) -> None:
    """Different profiles and beds along a branch, no inflow: nothing moves."""
    data = case_dict(
        hours=6.0, engine={"cross_sections": "interpolated"}, initial={"level": 2.0, "depth": 0.0},
        profiles=[{"id": "yz", "type": "yz", "y": [0, 3, 7, 10], "z": [2.5, 0, 0.2, 2.5]},
                  {"id": "zw", "type": "zw", "heights": [0, 1, 3], "flow_widths": [2, 6, 12]},
                  {"id": "rect", "type": "rectangular", "width": 5.0}],
        nodes=[{"id": "a"}, {"id": "b"}],
        branches=[{"id": "B", "from_node": "a", "to_node": "b", "length": 1000.0, "dx": 50.0,
                   "cross_sections": [{"chainage": 0.0, "profile": "yz", "bed_level": 0.5},
                                      {"chainage": 400.0, "profile": "zw", "bed_level": -0.3},
                                      {"chainage": 1000.0, "profile": "rect", "bed_level": 0.8}]}],
        boundaries=[],
    )
    out, _ = simulator(data, tmp_path).simulate(snapshots=True)
    assert np.abs(out.levels.to_numpy() - 2.0).max() < 1e-9
    assert np.abs(out.discharges.to_numpy()).max() < 1e-9


def test_a_water_level_friction_table_gives_the_normal_depth_of_its_coefficient_at_that_depth(
        tmp_path: Path) -> None:
    """A D-Flow FM branch whose Strickler coefficient is a ``waterLevel`` table (in a Chézy group), imported.

    The table at the two ends of the sloping branch is k = a + b (z - z_b), so interpolated in chainage and level as
    D-Flow FM does (flow1d ``getFrictionValue``) it is k = a + b h everywhere. The steady uniform depth solves
    Q = (a + b h) A R^(2/3) √S0 for the rectangle (scipy brentq), independently of the engine. Calculation points
    every 25 m: a link conveys at the level of its upwind point over the bed at its middle, an error of the scheme
    that shrinks with the spacing (here 5.5 mm at 100 m, 1.4 mm at 25 m; 3.5 and 0.9 mm with a constant k).
    """
    from rivercal.io.dhydro import import_dhydro
    from rivercal.model import load_model
    from tests.dhydro_models import write_uniform_model

    width, q, slope, (a, b), length = 8.0, 12.0, 2e-4, (18.0, 12.0), 4000.0

    def conveyance(h):
        area, radius = width * h, width * h / (width + 2.0 * h)
        return (a + b * h) * area * radius ** (2.0 / 3.0)

    hn = _normal_depth(conveyance, q, slope, 10.0)
    constant = _normal_depth(lambda h: (a + b * 1.0) * width * h * (width * h / (width + 2 * h)) ** (2 / 3), q,
                             slope, 10.0)
    assert abs(hn - constant) > 0.05  # the level dependence matters at this depth
    mdu = write_uniform_model(tmp_path / "model", q=q, slope=slope, width=width, depth=hn, strickler=(a, b),
                              length=length)
    result = import_dhydro(mdu, tmp_path / "case")
    assert result.ledger.status_of("friction on a branch", "B in roughness-Bed.ini") == "exact"
    sim = load_model(result.folder)
    out, _ = sim.simulate()
    depth = out.series["mid.h"] - slope * length / 2
    assert abs(depth.iloc[-1] - depth.iloc[-2]) < 1e-5  # steady
    assert depth.iloc[-1] == pytest.approx(hn, abs=2e-3)
