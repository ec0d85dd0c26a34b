"""The network features real models need, at the level of the compiled tables: each against a hand computation.

- friction sections of different laws, one of them depending on the water level, give the conveyance
  K = Σ K_s of the sections computed here from their areas and perimeters;
- cross-sections interpolated across a connection node into the next branch of the same order (D-Flow FM's
  branch orders): the bed level of every link between the last cross-section of one branch and the first of the
  next lies on the straight line between them; without an order (or with another) the nearest one holds;
- a summer dike adds its flow area to the floodplain by SOBEK 3's curve, without wetted perimeter; its storage
  follows SOBEK 3's rising curve and, once topped, its falling curve (the tables of both); between two
  cross-sections its crest, base and areas are interpolated (SOBEK 3's rule), not its curves;
- a branch's initial levels give the cold-start levels;
- bad friction entries are refused with the field that is wrong.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from rivercal.case import case_from_dict
from rivercal.engine import Simulator
from rivercal.engine.channels import extended_cross_sections, initial_levels
from rivercal.engine.compile import compile_network
from rivercal.engine.kernels.codes import FRICTION_CHEZY, FRICTION_MANNING, FRICTION_STRICKLER
from rivercal.engine.kernels.lookup import flow_geometry
from rivercal.engine.sections import dike_storage, flow_view, interpolate_tables, section_table
from rivercal.network import BranchFriction, FrictionGroup, ZWProfile

START = "2020-01-01T00:00:00Z"


def _case(profiles, branches, nodes, groups=None, engine=None) -> dict:
    ends = [n["id"] for n in nodes if sum(n["id"] in (b["from_node"], b["to_node"]) for b in branches) == 1]
    return {
        "case": {"name": "features", "start": START, "end": "2020-01-01T02:00:00Z"},
        "engine": {"dt": 60.0, **(engine or {})},
        "profiles": profiles, "nodes": nodes, "branches": branches,
        "friction_groups": groups or [],
        "boundaries": [{"id": "q", "node": ends[0], "type": "discharge", "value": 1.0},
                       {"id": "h", "node": ends[-1], "type": "level", "value": 1.0}],
    }


def _conveyance(compiled, link: int, depth: float, end: int = 1) -> float:
    """K (m³/s) the kernels use for ``link`` at ``depth`` over its bed: A √(C² R) from its table and its slot."""
    a = compiled.arrays
    prof = a.lk_p1[link] if end == 1 else a.lk_p2[link]
    area, per, r43 = flow_geometry.py_func(a.tab_off, a.tab_n, a.tab_idd, a.tab_top, a.tab_wf_top, a.tab_af,
                                           a.tab_pf, a.tab_flow, prof, depth)
    ftype = int(a.lk_ftype[link])
    value = compiled.friction_values[a.lk_fric[link]]
    if ftype == FRICTION_STRICKLER:  # C² R of each law: the kernels' friction term, written out
        c2r = value * value * r43
    elif ftype == FRICTION_MANNING:
        c2r = r43 / (value * value)
    elif ftype == FRICTION_CHEZY:
        c2r = value * value * area / per
    else:
        raise AssertionError(f"friction type {ftype}")
    return area * math.sqrt(c2r)


# -- friction sections of different laws -----------------------------------------------------------------


def test_sections_of_different_laws_and_a_level_dependent_one_sum_their_conveyance() -> None:
    levels, chezy = [0.0, 3.0, 6.0], [10.0, 25.0, 40.0]
    profiles = [{"id": "river", "type": "zw", "heights": [0.0, 2.0, 2.0001, 4.0], "flow_widths": [10, 10, 60, 60],
                 "section_widths": [10.0, 50.0], "friction": ["main", "flood"]}]
    groups = [{"id": "main", "type": "manning", "value": 0.03, "branches": [{"branch": "B", "type": "strickler",
                                                                             "value": 35.0}]},
              {"id": "flood", "type": "chezy", "value": 30.0,
               "branches": [{"branch": "B", "function": "waterlevel", "levels": levels, "table": [chezy]}]}]
    nodes = [{"id": "u"}, {"id": "d"}]
    branches = [{"id": "B", "from_node": "u", "to_node": "d", "length": 1000.0, "dx": 500.0,
                 "cross_sections": [{"chainage": 0.0, "profile": "river", "bed_level": 0.5}]}]
    case = case_from_dict(_case(profiles, branches, nodes, groups), Path("."))
    compiled = compile_network(case.network, case.spec.engine)
    link = 0
    assert compiled.friction_slots[compiled.arrays.lk_fric[link]] == ("group", "main", "B")  # its own law
    bed = float(compiled.arrays.lk_b1[link])
    for h in (1.0, 2.5, 3.7):
        a_main, p_main = 10.0 * h, 10.0 + 2.0 * min(h, 2.0)
        k = 35.0 * a_main * (a_main / p_main) ** (2.0 / 3.0)
        if h > 2.0001:
            a_fp = 50.0 * (h - 2.0001) + 25.0 * 1e-4
            p_fp = 50.0 + 2.0 * (h - 2.0001)
            k += np.interp(bed + h, levels, chezy) * a_fp * math.sqrt(a_fp / p_fp)
        assert _conveyance(compiled, link, h) == pytest.approx(k, rel=2e-3), h


def test_a_water_level_table_scales_with_the_group_value() -> None:
    profiles = [{"id": "r", "type": "rectangular", "width": 10.0, "friction": ["g"]}]
    groups = [{"id": "g", "type": "manning", "value": 0.03,
               "branches": [{"branch": "B", "function": "waterlevel", "levels": [0.0, 10.0],
                             "table": [[0.04, 0.02]]}]}]
    nodes = [{"id": "u"}, {"id": "d"}]
    branches = [{"id": "B", "from_node": "u", "to_node": "d", "length": 1000.0, "dx": 500.0,
                 "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": 2.0}]}]
    sim = Simulator(case_from_dict(_case(profiles, branches, nodes, groups), Path(".")))
    c = sim.compiled
    assert c.friction_slots[c.arrays.lk_fric[0]] == ("group", "g")  # the table sits on the group's slot
    h = 1.5
    n = np.interp(float(c.arrays.lk_b1[0]) + h, [0.0, 10.0], [0.04, 0.02])
    expected = 10.0 * h * (10.0 * h / (10.0 + 2 * h)) ** (2 / 3) / n
    assert _conveyance(c, 0, h) == pytest.approx(expected, rel=1e-6)
    _, fric = sim.parameter_arrays({"friction:group:g": 0.06})  # twice the group's n: half the conveyance
    assert fric[c.arrays.lk_fric[0]] == 0.06
    assert "friction:group:g" in sim.default_parameters()


def test_a_group_that_shares_a_profile_with_another_is_refused_as_a_target_and_says_why() -> None:
    """A link's conveyance holds all sections of its profile relative to the first section's group.

    So a change of ``banks`` (a second section) alone would not reach any conveyance, and one of ``bed`` (the first)
    would scale the banks as well: both are refused by name; ``friction:scale`` (every section alike, exact for
    Manning) and a group that no profile mixes with another stay targets.
    """
    profiles = [{"id": "river", "type": "zw", "heights": [0.0, 2.0, 3.0], "flow_widths": [10.0, 10.0, 60.0],
                 "section_widths": [10.0, 50.0], "friction": ["bed", "banks"]},
                {"id": "ditch", "type": "rectangular", "width": 4.0, "friction": ["ditch"]}]
    groups = [{"id": "bed", "type": "manning", "value": 0.03}, {"id": "banks", "type": "manning", "value": 0.06},
              {"id": "ditch", "type": "manning", "value": 0.04}]
    nodes = [{"id": "u"}, {"id": "m"}, {"id": "d"}]
    branches = [{"id": "B", "from_node": "u", "to_node": "m", "length": 1000.0, "dx": 500.0,
                 "cross_sections": [{"chainage": 0.0, "profile": "river", "bed_level": 2.0}]},
                {"id": "C", "from_node": "m", "to_node": "d", "length": 1000.0, "dx": 500.0,
                 "cross_sections": [{"chainage": 0.0, "profile": "ditch", "bed_level": 1.0}]}]
    sim = Simulator(case_from_dict(_case(profiles, branches, nodes, groups), Path(".")))
    for group, effect in (("banks", "would not change the conveyance"), ("bed", "would scale the conveyance of its "
                                                                                "other sections (banks)")):
        with pytest.raises(KeyError) as info:
            sim.parameter_arrays({f"friction:group:{group}": 0.05})
        message = str(info.value)
        assert "profile 'river'" in message and effect in message and "friction:scale" in message
        assert f"friction:group:{group}" not in sim.default_parameters()
    assert "friction:group:ditch" in sim.default_parameters()
    _, fric = sim.parameter_arrays({"friction:scale": 2.0})  # every section's conveyance doubles
    assert fric[sim.compiled.arrays.lk_fric[0]] == pytest.approx(0.015)  # the river's link: bed's n halved


# -- branch orders -----------------------------------------------------------------------------------------


def _two_branches(order1, order2, mode="interpolated"):
    profiles = [{"id": "r", "type": "rectangular", "width": 10.0}]
    nodes = [{"id": "A"}, {"id": "B"}, {"id": "C"}]
    branches = [{"id": "b1", "from_node": "A", "to_node": "B", "length": 1000.0, "dx": 100.0,
                 "cross_sections": [{"chainage": 200.0, "profile": "r", "bed_level": 5.0}]},
                {"id": "b2", "from_node": "B", "to_node": "C", "length": 1000.0, "dx": 100.0,
                 "cross_sections": [{"chainage": 600.0, "profile": "r", "bed_level": 3.0}]}]
    for b, order in zip(branches, (order1, order2), strict=True):
        if order is not None:
            b["order"] = order
    case = case_from_dict(_case(profiles, branches, nodes, engine={"cross_sections": mode}), Path("."))
    return case, compile_network(case.network, case.spec.engine)


def test_branches_of_the_same_order_interpolate_their_cross_sections_across_the_node() -> None:
    case, c = _two_branches(1, 1)
    # by hand: b1's cross-section at 200 m (5 m AD) and b2's at 600 m (3 m AD) are 800 + 600 = 1400 m apart
    for li, (branch, chainage) in enumerate(zip(c.link_branch, c.link_chainage, strict=True)):
        along = chainage - 200.0 if branch == "b1" else 800.0 + chainage
        expected = 5.0 + (3.0 - 5.0) * np.clip(along, 0.0, 1400.0) / 1400.0
        assert c.arrays.lk_b1[li] == pytest.approx(expected, abs=1e-12), (branch, chainage)
    node_b = c.hp_label.index("node:B")
    assert c.arrays.hp_bed[node_b] == pytest.approx(5.0 - 2.0 * 850.0 / 1400.0, abs=1e-12)  # its lower half-link
    extended = extended_cross_sections(case.network)
    assert [round(ch, 6) for ch, _, _ in extended["b1"]] == [200.0, 1600.0]
    assert [round(ch, 6) for ch, _, _ in extended["b2"]] == [-800.0, 600.0]


@pytest.mark.parametrize(("order1", "order2"), [(None, None), (-1, -1), (1, 2)])
def test_without_a_common_order_the_nearest_cross_section_holds_to_the_node(order1, order2) -> None:
    _, c = _two_branches(order1, order2)
    for li, (branch, chainage) in enumerate(zip(c.link_branch, c.link_chainage, strict=True)):
        if branch == "b1" and chainage > 200.0:
            assert c.arrays.lk_b1[li] == 5.0
        if branch == "b2" and chainage < 600.0:
            assert c.arrays.lk_b1[li] == 3.0


# -- summer dike -------------------------------------------------------------------------------------------


_DIKE_PROFILE = {"id": "p", "type": "zw", "heights": [0.0, 2.0, 2.5, 6.0], "flow_widths": [20.0, 20.0, 80.0, 80.0],
                 "section_widths": [20.0, 60.0]}


def _sobek_dike(level: float, crest: float, base: float, area: float, transition: float, falling: bool) -> float:
    """SOBEK 3's summer dike area at ``level`` (flow1d GetSummerDikeFlow/GetSummerDikeTotal, written out here)."""
    low, span = (base, crest + transition - base) if falling else (crest, transition)
    if level > low + span:
        return area
    if level > low + 0.5 * span:  # the width falls linearly from its peak at half the span to 0 at its end
        width = (low + span - level) * 4.0 * area / span / span
        return area - 0.5 * (low + span - level) * width
    if level > low:
        width = (level - low) * 4.0 * area / span / span
        return 0.5 * (level - low) * width
    return 0.0


def test_a_summer_dike_adds_flow_area_without_perimeter_and_leaves_the_storage_to_its_own_tables() -> None:
    crest, base, flow, total, transition = 3.0, 2.2, 120.0, 200.0, 0.5
    bare = section_table(ZWProfile.model_validate(_DIKE_PROFILE))
    table = section_table(ZWProfile.model_validate({**_DIKE_PROFILE, "summer_dike": {
        "crest": crest, "flow_area": flow, "total_area": total, "transition": transition, "base": base}}))
    dike = flow_view(table)
    for d in (2.9, 3.1, 3.25, 3.4, 3.6, 5.0):
        k = round(d / bare.depth[1])
        assert dike.area[k] - bare.area[k] == pytest.approx(
            _sobek_dike(bare.depth[k], crest, base, flow, transition, False), abs=1e-9)
        assert dike.total[k] == bare.total[k]  # the storage is a contribution of its own
        assert dike.perimeter[k] == bare.perimeter[k]
        assert dike.part_area[0, k] == bare.part_area[0, k]  # the floodplain takes it, not the main channel
    rising, falling = dike_storage(table.dike)
    for curve, is_falling in ((rising, False), (falling, True)):
        at, top = curve[2], curve[6]
        depth = np.linspace(0.0, top, at.size)
        assert top == pytest.approx(crest + transition - base)
        for level in np.linspace(base - 0.3, crest + transition + 0.3, 37):  # the tables from the base, linear
            table_value = np.interp(level - base, depth, at, left=0.0)
            assert table_value == pytest.approx(_sobek_dike(level, crest, base, total, transition, is_falling),
                                                abs=2e-4 * total)
    assert falling[2][-1] == rising[2][-1] == total  # both full at the full height: no jump when switching


def test_between_two_cross_sections_a_summer_dike_is_interpolated_by_its_crest_base_and_areas() -> None:
    def dike(crest, base, area):
        return section_table(ZWProfile.model_validate({**_DIKE_PROFILE, "summer_dike": {
            "crest": crest, "flow_area": area, "total_area": area, "base": base}}))

    a, b = dike(3.0, 2.0, 100.0), dike(4.0, 3.0, 300.0)
    mid = interpolate_tables(a, b, 0.25).dike
    assert (mid.crest, mid.base, mid.flow_area, mid.total_area) == pytest.approx((3.25, 2.25, 150.0, 150.0))
    one_sided = interpolate_tables(a, section_table(ZWProfile.model_validate(_DIKE_PROFILE)), 0.25).dike
    # SOBEK 3's interpolateSummerDike: the other side counts as a dike of no area at its lowest point
    assert (one_sided.crest, one_sided.base, one_sided.total_area) == pytest.approx((2.25, 1.5, 75.0))


# -- initial levels ------------------------------------------------------------------------------------------


def test_initial_levels_along_branches_give_the_cold_start() -> None:
    profiles = [{"id": "r", "type": "rectangular", "width": 10.0}]
    nodes = [{"id": "A"}, {"id": "B"}, {"id": "C"}]
    branches = [{"id": "b1", "from_node": "A", "to_node": "B", "length": 1000.0, "dx": 250.0,
                 "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": 2.0}],
                 "initial_levels": {"chainages": [0.0, 1000.0], "levels": [6.0, 4.0]}},
                {"id": "b2", "from_node": "B", "to_node": "C", "length": 1000.0, "dx": 250.0,
                 "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": 3.5}],
                 "initial_levels": {"chainages": [500.0], "levels": [3.0]}}]
    data = _case(profiles, branches, nodes)
    data["initial"] = {"depth": 0.25}
    sim = Simulator(case_from_dict(data, Path(".")))
    c = sim.compiled
    along = initial_levels(sim.case.network, c.hp_label, c.hp_branch, c.hp_chainage)
    at = {label: float(v) for label, v in zip(c.hp_label, along, strict=True)}
    assert at["b1@250.0"] == pytest.approx(5.5)
    assert at["node:B"] == pytest.approx(0.5 * (4.0 + 3.0))
    z = sim.initial_state().z
    level = dict(zip(c.hp_label, z, strict=True))
    assert level["b1@500.0"] == pytest.approx(5.0)
    assert level["b2@250.0"] == pytest.approx(3.5)  # 3 m AD lies below the bed (3.5 m AD): dry
    assert level["node:C"] == pytest.approx(1.0)  # the level boundary


# -- bad entries -----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("entry", "field", "words"), [
    ({"value": 0.03, "values": [0.03], "chainages": [0.0]}, "value", "either value"),
    ({"chainages": [0.0, 10.0], "values": [0.03]}, "values", "one value per chainage"),
    ({"chainages": [10.0, 5.0], "values": [0.03, 0.04]}, "chainages[1]", "increase strictly"),
    ({"function": "waterlevel", "levels": [1.0, 0.0], "table": [[0.03, 0.03]]}, "levels[1]", "increase strictly"),
    ({"function": "waterlevel", "levels": [0.0, 1.0], "table": [[0.03]]}, "table[0]", "one value per level"),
    ({"function": "waterlevel", "levels": [0.0], "chainages": [0.0, 5.0], "table": [[0.03]]}, "table",
     "one row per chainage"),
    ({"function": "waterlevel", "levels": [0.0], "table": [[-0.03]]}, "table[0][0]", "positive"),
    ({"function": "waterlevel", "value": 0.03}, "value", "levels and table"),
])
def test_a_bad_branch_friction_names_its_field(entry, field, words) -> None:
    with pytest.raises(ValidationError) as info:
        BranchFriction.model_validate({"branch": "B", **entry})
    text = str(info.value)
    assert field in text and words in text, text


def test_a_table_in_the_wrong_unit_is_caught_by_its_largest_value() -> None:
    with pytest.raises(ValidationError, match=r"branches\[0\]\.table.*manning coefficient 30"):
        FrictionGroup.model_validate({"id": "g", "type": "manning", "value": 0.03, "branches": [
            {"branch": "B", "function": "waterlevel", "levels": [0.0, 1.0], "table": [[25.0, 30.0]]}]})
    group = FrictionGroup.model_validate({"id": "g", "type": "chezy", "value": 40.0, "branches": [
        {"branch": "B", "function": "waterlevel", "levels": [0.0, 1.0], "table": [[0.02, 35.0]]}]})
    assert group.entry("B").coefficient_at(0.0)[1].tolist() == [0.02, 35.0]  # a dry floodplain's low values stay


def test_a_white_colebrook_table_gives_the_conveyance_of_its_law() -> None:
    levels, kn = [0.0, 4.0], [0.2, 0.02]  # m AD, m: smoother as the water rises
    profiles = [{"id": "r", "type": "rectangular", "width": 10.0, "friction": ["g"]}]
    groups = [{"id": "g", "type": "white-colebrook", "value": 0.05,
               "branches": [{"branch": "B", "function": "waterlevel", "levels": levels, "table": [kn]}]}]
    nodes = [{"id": "u"}, {"id": "d"}]
    branches = [{"id": "B", "from_node": "u", "to_node": "d", "length": 1000.0, "dx": 500.0,
                 "cross_sections": [{"chainage": 0.0, "profile": "r", "bed_level": 1.0}]}]
    c = compile_network(*(lambda k: (k.network, k.spec.engine))(case_from_dict(
        _case(profiles, branches, nodes, groups), Path("."))))
    a = c.arrays
    for h in (0.5, 1.5, 2.5):
        area, per, _ = flow_geometry.py_func(a.tab_off, a.tab_n, a.tab_idd, a.tab_top, a.tab_wf_top, a.tab_af,
                                             a.tab_pf, a.tab_flow, a.lk_p1[0], h)
        k_slot = c.friction_values[a.lk_fric[0]]
        radius = area / per  # the kernels' White-Colebrook: C = 18 log10(12 R / k_n) with the slot's k_n
        engine = area * 18.0 * math.log10(12.0 * radius / k_slot) * math.sqrt(radius)
        r_true = 10.0 * h / (10.0 + 2.0 * h)
        k_true = np.interp(float(a.lk_b1[0]) + h, levels, kn)
        expected = 10.0 * h * 18.0 * math.log10(12.0 * r_true / k_true) * math.sqrt(r_true)
        assert engine == pytest.approx(expected, rel=1e-5), h  # the table: linear between its 2000 depths
