"""A friction factor on the imported D-HYDRO Dellen: bit for bit the case with the coefficients scaled by hand.

Dellen (LGPL, read from ../shared/data) conveys most of its branches with the own value of a friction group that
other branches share (``Strickler_35.0``, ``Manning_0.03``). A factor on 20 of them gives each a friction slot of
its own: with factor 1 the run is bit for bit the case without the factor, and with factor 1.5 it is bit for bit
the case in which each of those branches gets the group's value times 1.5 (k_s) or divided by it (n) in the
group's own ``branches`` table — the form a modeller would write by hand. Cost: about 4 s of processor time
(the import, three compilations and three runs of two hours of the 171-branch model).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from rivercal.case import load_case
from rivercal.engine import Simulator
from rivercal.io.dhydro import ImportOptions, import_dhydro
from tests.shared_data import shared_model

F = 1.5


def test_a_factor_on_twenty_dellen_branches_is_the_hand_scaled_case(tmp_path: Path) -> None:
    mdu = shared_model("dhydro-dellen", "dflowfm", "Flow1D.mdu")
    import_dhydro(mdu, tmp_path / "case", ImportOptions(realtime_lateral=0.0))
    text = (tmp_path / "case" / "case.toml").read_text(encoding="utf-8")
    base = Simulator(load_case(tmp_path / "case"))
    c = base.compiled
    shared: dict[str, str] = {}  # branch → the group whose shared value its links convey with
    for link, branch in enumerate(c.link_branch):
        key = c.friction_slots[int(c.arrays.lk_fric[link])]
        if key[0] == "group" and len(key) == 2:
            shared.setdefault(branch, key[1])
    picked = list(shared)[:20]
    laws = {"Strickler_35.0": ("strickler", 35.0), "Manning_0.03": ("manning", 0.03)}
    assert {shared[b] for b in picked} <= set(laws) and len(picked) == 20

    def case(name: str, body: str) -> Path:
        folder = tmp_path / name
        folder.mkdir()
        for item in (tmp_path / "case").iterdir():
            if item.name != "case.toml":
                (folder / item.name).symlink_to(item)
        (folder / "case.toml").write_text(body, encoding="utf-8")
        return folder

    listed = ", ".join(f'"{b}"' for b in picked)
    declared = f'\n[[friction_factors]]\nid = "creek"\nbranches = [{listed}]\n'
    factored = Simulator(load_case(case("factor", text + declared)))
    assert len(factored.compiled.friction_slots) > len(c.friction_slots)
    hand_text = text
    for gid, (law, value) in laws.items():
        scaled = value * F if law == "strickler" else value / F
        entries = ", ".join(f'{{ branch = "{b}", value = {scaled!r} }}' for b in picked if shared[b] == gid)
        old = f'{{ id = "{gid}", type = "{law}", value = {value} }}'
        assert old in hand_text
        hand_text = hand_text.replace(old, old[:-2] + f", branches = [{entries}] }}")
    by_hand = Simulator(load_case(case("hand", hand_text)))

    end = base.start + pd.Timedelta("2h")
    plain = base.simulate({}, end=end)[0].series
    pd.testing.assert_frame_equal(factored.simulate({"friction:factor:creek": 1.0}, end=end)[0].series, plain,
                                  check_exact=True)
    scaled = factored.simulate({"friction:factor:creek": F}, end=end)[0].series
    pd.testing.assert_frame_equal(scaled, by_hand.simulate({}, end=end)[0].series, check_exact=True)
    levels = [col for col in plain.columns if col.endswith(".h")]
    assert (scaled[levels] - plain[levels]).abs().max().max() > 0.002  # the factor moves the levels (by 5 mm)
