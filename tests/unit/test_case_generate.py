"""Generated lowland networks: valid cases of the size asked, with the features promised, that run soundly.

The checks are independent of the generator's code: the network is read back through the case loader and
the engine's compiled grid (points, links, structures), its graph is examined with plain counting (a tree
has one branch fewer than nodes; every extra branch closes a loop), and a run is checked against the
volume balance (stored volume change = what entered through boundaries and laterals, to round-off).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from rivercal.case import load_case
from rivercal.case.generate import generate_case
from rivercal.cli.main import app
from rivercal.model import build_model


@pytest.fixture(scope="module")
def generated(tmp_path_factory) -> tuple[Path, object]:
    folder = tmp_path_factory.mktemp("gen") / "case"
    made = generate_case(folder, 6000, seed=7)
    return folder, made


def test_the_case_loads_with_about_the_points_asked_and_every_feature(generated) -> None:
    folder, made = generated
    case = load_case(folder)
    model = build_model(case)
    net = case.network
    assert 0.85 * 6000 <= model.compiled.n_hpoints <= 1.15 * 6000
    assert made.catchments == 2 and len(net.branches) == made.branches + made.catchments  # + the trunk reaches
    # loops: a connected graph with more branches than nodes - 1 has that many independent cycles
    assert len(net.branches) - (len(net.nodes) - 1) >= 3
    # bifurcations: a node with two branches leaving it downstream
    starts = pd.Series([b.from_node for b in net.branches]).value_counts()
    assert (starts >= 2).any()
    # a weir about every kilometre of stream (the trunk canal has none)
    stream_km = sum(b.length for b in net.branches if not b.id.startswith("T")) / 1000.0
    assert 0.7 <= len(net.weirs) / stream_km <= 1.1
    assert len(net.culverts) >= 5 and len(net.laterals) == made.laterals >= made.branches
    assert len(net.stations) == made.stations >= 20
    assert {p.name for p in case.spec.parameters} >= {"FA", *(f"F{k}" for k in range(1, 21))}


def test_the_same_seed_gives_the_same_files_and_another_seed_another_network(generated, tmp_path: Path) -> None:
    folder, _ = generated
    again = generate_case(tmp_path / "again", 6000, seed=7)
    other = generate_case(tmp_path / "other", 6000, seed=8)
    for name in ("case.toml", "forcing.csv"):
        assert (again.path / name).read_bytes() == (folder / name).read_bytes()
    assert (other.path / "case.toml").read_bytes() != (folder / "case.toml").read_bytes()


@pytest.mark.slow  # about 6 s: the 48 h spin-up (half of it) and 54 hours of a 6000-point network
def test_the_first_storm_on_a_generated_network_keeps_its_water_balance(generated) -> None:
    """Hours 66-120: the first storm's rain starts 70-94 h in and peaks 88-112 h in, by catchment.

    Before 70 h the inflows are the constant base flow, so a cold start at 66 h (the case's spin-up at that
    base flow) meets the storm in a state of that base flow, as a run from the case's start does.
    """
    folder, _ = generated
    model = build_model(load_case(folder))
    start = model.start + pd.Timedelta(hours=66)
    result, _ = model.simulate(None, start=start, end=model.start + pd.Timedelta(days=5))
    bal = result.balance
    throughput = abs(bal.initial) + sum(abs(v) for v in bal.boundaries.values()) + abs(bal.laterals)
    assert abs(bal.residual) <= 1e-9 * throughput
    assert np.all(np.isfinite(result.series.to_numpy()))
    levels = result.series.filter(regex=r"\.h(_up|_down)?$")
    assert (levels.diff().abs().max() < 1.0).all()  # hourly level changes of a lowland storm, not jumps
    assert bal.laterals > 0 and bal.boundaries["end"] < 0  # rain comes in, the trunk's end lets it out


def test_the_command_writes_a_case_and_refuses_bad_sizes(tmp_path: Path) -> None:
    runner = CliRunner()
    done = runner.invoke(app, ["case", "generate", "--points", "500", "--out", str(tmp_path / "c"), "--json"])
    assert done.exit_code == 0, done.output
    summary = json.loads(done.stdout)
    assert summary["branches"] >= 5 and (tmp_path / "c" / "case.toml").is_file()
    bad = runner.invoke(app, ["case", "generate", "--points", "10", "--out", str(tmp_path / "d")])
    assert bad.exit_code == 2 and "--points" in bad.output
    again = runner.invoke(app, ["case", "generate", "--points", "600", "--out", str(tmp_path / "c"), "--json"])
    assert again.exit_code == 0, again.output  # a generated case is replaced
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "case.toml").write_text('[case]\nname = "dommel"\n', encoding="utf-8")
    kept = runner.invoke(app, ["case", "generate", "--points", "500", "--out", str(mine)])
    assert kept.exit_code == 2 and "did not write" in kept.output and "--out" in kept.output
    assert (mine / "case.toml").read_text(encoding="utf-8") == '[case]\nname = "dommel"\n'
    assert not (mine / "forcing.csv").exists()


@pytest.mark.slow  # about 6 s: five days (the first storm) of two 1500-point networks
def test_a_five_minute_step_gives_the_levels_of_the_one_minute_step_to_centimetres(tmp_path: Path) -> None:
    fine = generate_case(tmp_path / "fine", 1500, seed=3)
    coarse = generate_case(tmp_path / "coarse", 1500, seed=3, dt=300.0)
    text = (coarse.path / "case.toml").read_text(encoding="utf-8")
    assert text.splitlines()[0].endswith("--dt 300") and "--dt 300`" in (coarse.path / "README.md").read_text()
    assert text.replace("dt = 300.0", "dt = 60.0").splitlines()[1:] == \
        (fine.path / "case.toml").read_text(encoding="utf-8").splitlines()[1:]  # the same network
    series = {}
    for made in (fine, coarse):
        model = build_model(load_case(made.path))
        series[model.dt], _ = model.simulate(None, end=model.start + pd.Timedelta(days=5))
    assert set(series) == {60.0, 300.0}
    levels = [r.series.filter(regex=r"\.h(_up|_down)?$") for r in (series[60.0], series[300.0])]
    diff = (levels[1] - levels[0]).abs().to_numpy()
    rise = float((levels[0].max() - levels[0].min()).median())
    assert rise > 0.1  # the storm moves the levels by decimetres
    assert np.percentile(diff, 99) < 0.005 and diff.max() < 0.05  # mm mostly; cm where a weir changes regime


def test_the_time_step_must_divide_the_output_interval(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="dt must be a divisor of 3600"):
        generate_case(tmp_path / "c", 500, dt=700.0)
    bad = CliRunner().invoke(app, ["case", "generate", "--points", "500", "--dt", "0", "--out", str(tmp_path / "d")])
    assert bad.exit_code == 2 and "--dt 0" in bad.output and not (tmp_path / "d").exists()
