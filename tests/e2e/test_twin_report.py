"""``rivercal twin``: a small thesis-style run through the CLI writes index.html with ours beside the thesis'.

One short suite (F1W0, three scenarios, a one-day window early in the case so that the truths need little
spin-up) and the initial analysis of two parameters: ~30 model runs, well under a minute on 2 cores.
"""

from __future__ import annotations

import json
from html.parser import HTMLParser
from pathlib import Path

import pytest

from tests.cli import rivercal

WINDOW = "2010-09-03/2010-09-04"


class _Images(HTMLParser):
    def __init__(self):
        super().__init__()
        self.srcs: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.srcs.append(dict(attrs)["src"])

    def handle_data(self, data):
        self.text.append(data)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("twin")
    done = rivercal("twin", "dommel", "--suite", "F1W0,sensitivity", "--scenarios", "H1,M2,L2", "--window", WINDOW,
                    "--params", "W2,FA", "--workers", "2", "--out", str(out), "--json")
    assert done.returncode == 0, done.stderr
    return out, json.loads(done.stdout)


def test_index_html_holds_our_numbers_and_the_thesis_numbers(run: tuple[Path, dict]) -> None:
    out, summary = run
    page = out / "index.html"
    assert summary["report"] == str(page)
    parser = _Images()
    parser.feed(page.read_text(encoding="utf-8"))
    text = "".join(parser.text)
    # ours: the calibrated values, iterations and the sensitivity's largest cost, as the run reported them
    rows = {r["id"]: r for r in _csv(out / "F1W0.csv")}
    assert set(rows) == {"H1", "M2", "L2"}
    for row in rows.values():
        assert f"{float(row['F1_estimate']):.6g}" in text
        assert abs(float(row["F1_estimate"]) - float(row["F1_true"])) <= 0.05
    f1w0 = summary["suites"]["F1W0"]
    assert f1w0["robustness"] == 1.0 and f1w0["scenarios"] == 3
    assert f"max {f1w0['iterations_max']} (" in text
    ranking = summary["sensitivity"]["sensitivity"]["ranking"]
    assert {r["parameter"] for r in ranking} == {"W2", "FA"}
    assert f"{ranking[0]['max_cost']:.4g}" in text
    verdict = summary["sensitivity"]["identifiability"]["verdict"]
    assert set(verdict) == {"W2", "FA"}
    # the thesis': Table 4-5/4-6 values of the same scenarios, and the sensitivity ranking of §4-5-1
    for printed in ("19.9997", "12.0002", "1.34e-09", "3.57e-09"):
        assert printed in text, printed
    assert "W2, FA, W3, W5" in text
    assert "Where and why our results differ from the thesis" in text


def test_index_html_links_existing_pngs_relatively(run: tuple[Path, dict]) -> None:
    out, _ = run
    parser = _Images()
    parser.feed((out / "index.html").read_text(encoding="utf-8"))
    expected = {"sensitivity.png", "sensitivity_stations.png", "svd.png", "correlation.png", "F1W0_convergence.png",
                "F1W0_cost.png", "F1W0_H1_levels.png", "F1W0_bias.png"}
    assert set(parser.srcs) == expected
    for src in parser.srcs:
        assert not Path(src).is_absolute()
        png = out / src
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", src


def test_bias_of_eq_2_14_per_scenario_and_targets(run: tuple[Path, dict]) -> None:
    out, summary = run
    bias = _csv(out / "F1W0_bias.csv")
    assert {r["scenario"] for r in bias} == {"H1", "M2", "L2"}
    assert {r["series"] for r in bias} == {"0028.h_down"}  # the station of thesis Fig. 4-11
    rows = _csv(out / "F1W0.csv")
    assert all(r["bias_eq214_series"] == "0028.h_down" for r in rows)
    targets = {t["target"]: t for t in summary["targets"]}
    iterations = targets["F1W0: at most 6 DuD iterations"]
    assert iterations["met"] == (summary["suites"]["F1W0"]["iterations_max"] <= 6)
    assert targets["FaWc: robustness 100 % (|ΔFA| ≤ 0.05, |ΔWc| ≤ 0.002)"]["met"] is None  # not run
    wall = targets["whole thesis run ≤ 10 min wall on 2 cores"]
    assert wall["met"] is None and "not judged" in wall["measured"]  # a partial run is not judged


@pytest.mark.parametrize(("args", "message"), [
    (["--suite", "F1W0,nope"], "--suite 'nope': choose from"),
    (["--suite", "thesis", "--scenarios", "H1"], "suite FaWc has none of them"),
    (["--suite", "F1W0", "--scenarios", "H1,X7"], "no chosen suite has a scenario 'X7'"),
    (["--suite", "sensitivity", "--params", "W2,Q9"], "--params: unknown parameter 'Q9'"),
])
def test_bad_input_exits_2_before_any_run(tmp_path: Path, args: list[str], message: str) -> None:
    done = rivercal("twin", "dommel", *args, "--out", str(tmp_path))
    assert done.returncode == 2
    assert message in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "index.html").exists()


def _csv(path: Path) -> list[dict]:
    import csv

    with path.open(encoding="utf-8") as f:
        return list(csv.DictReader(f))
