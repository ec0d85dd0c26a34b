"""The documentation site builds as ``make docs`` builds it, and holds what it promises.

One build of a copy of ``docs/`` (so that a build here never races ``make docs`` in the work tree), with
warnings as errors; the tutorial is executed by that build. Then: every public name of rivercal has an
entry in the site's object inventory, the tutorial page shows the figures and numbers its run produced,
the command-line and schema references cover every command and object, and no page loads anything from
another host.
"""

from __future__ import annotations

import importlib
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
#: What a build writes into docs/ (relative paths): left out of the copy, so that the copy builds from scratch.
GENERATED = ("_build", "tutorial", "explanation/verification", "reference/generated", "reference/api",
             "sg_execution_times.rst")


def _generated(folder: str, names: list[str]) -> set[str]:
    """shutil.copytree's ignore: the build's outputs (by path under docs/) and caches."""
    here = Path(folder).relative_to(DOCS)
    return {n for n in names if n == "__pycache__" or (here / n).as_posix() in GENERATED}

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    source = tmp_path_factory.mktemp("docs") / "docs"
    shutil.copytree(DOCS, source, ignore=_generated)
    # the pages include files of the packaged cases (../../src/rivercal/cases/...): one source for both
    shutil.copytree(ROOT / "src" / "rivercal" / "cases", source.parent / "src" / "rivercal" / "cases",
                    ignore=shutil.ignore_patterns("__pycache__"))
    html = source / "_build" / "html"
    run = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-E", "-W", "--keep-going", "-q",
                          str(source), str(html)], capture_output=True, text=True, cwd=source)
    assert run.returncode == 0, f"sphinx-build failed:\n{run.stderr[-6000:]}"
    return html


def _extension():
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        return importlib.import_module("rivercal_docs")
    finally:
        sys.path.remove(str(DOCS / "_ext"))


def test_every_public_name_has_a_reference_entry(site: Path) -> None:
    from sphinx.util.inventory import InventoryFile

    with open(site / "objects.inv", "rb") as f:
        inventory = InventoryFile.load(f, "", lambda base, uri: uri)
    entries_by_kind = getattr(inventory, "data", inventory)  # a plain dict before Sphinx 8.2
    documented = {name for kind, entries in entries_by_kind.items() if kind.startswith("py:") for name in entries}
    public = _extension().public_names()
    assert len(public) > 100
    missing = []
    for module, names in public.items():
        mod = importlib.import_module(module)
        for name in names:
            obj = getattr(mod, name)
            # documented under its own path, or once under another public path of the same object
            paths = {f"{m}.{n}" for m, ns in public.items() for n in ns
                     if n == name and getattr(importlib.import_module(m), n) is obj}
            if not paths & documented:
                missing.append(f"{module}.{name}")
    assert not missing, f"public names without a reference entry: {missing}"


def test_tutorial_page_shows_its_run(site: Path) -> None:
    page = (site / "tutorial" / "plot_calibrate_dommel.html").read_text(encoding="utf-8")
    images = re.findall(r'<img[^>]+src="([^"]+sphx_glr_plot_calibrate_dommel_\d+\.png)"', page)
    assert len(set(images)) >= 4, images
    for src in images:
        assert (site / "tutorial" / src).resolve().is_file(), src
    # the numbers of the run: the fit report, the on-line cycles and the store's tables
    assert "[[Estimates]]" in page and "[[Correlations]]" in page
    assert re.search(r"FA: 2\d\.\d+ \+/- ", page), "the calibrated friction is near its true 20 m^(1/3)/s"
    assert "not identifiable" in page
    assert page.count("done") >= 3


def test_verification_page_shows_the_engine_against_its_references(site: Path) -> None:
    page = (site / "explanation" / "verification" / "plot_engine_verification.html").read_text(encoding="utf-8")
    images = set(re.findall(r'<img[^>]+src="([^"]+sphx_glr_plot_engine_verification_\d+\.png)"', page))
    assert len(images) >= 3, images  # backwater curves, weir rating, convergence
    errors_mm = [float(e) for e in re.findall(r"largest error (\d+\.\d) mm against the GVF ODE", page)]
    assert len(errors_mm) == 2 and max(errors_mm) < 5.0, errors_mm  # M1 and M2 against the ODE, as the tests ask
    weir = float(re.search(r"largest difference from Eq. 3-4 ([0-9.e+-]+) %", page).group(1))
    assert weir < 0.1
    relative = float(re.search(r"residual \S+ m³, relative ([0-9.eE+-]+)", page).group(1))
    assert abs(relative) < 1e-10  # the volume balance of the default case closes to round-off
    moves = [float(m) for m in re.search(r"the peak moves ([0-9.]+), ([0-9.]+), ([0-9.]+) mm", page).groups()]
    assert max(moves) < 10.0 and moves[2] < moves[1]  # converges under refinement, as the convergence test asks


def test_explanations_carry_the_evidence_tables(site: Path) -> None:
    optimisers = (site / "explanation" / "optimisers.html").read_text(encoding="utf-8")
    for name in ("dud", "sparse_dud", "trf", "sce_ua", "dds", "grid", "glue"):
        assert f"<code class=\"docutils literal notranslate\"><span class=\"pre\">{name}</span></code>" in optimisers
    assert "19/19" in optimisers and "1859 observations" in optimisers  # the NIST summary and the twin table
    guides = {p.stem for p in (site / "howto").glob("*.html")}
    assert {"own-network", "dhydro-model", "external-model", "daily-service", "fews", "dashboard", "dask"} <= guides


def test_command_and_schema_references_are_complete(site: Path) -> None:
    import typer

    from rivercal.cli.main import app

    cli = (site / "reference" / "cli.html").read_text(encoding="utf-8")
    root = typer.main.get_command(app)
    for name, command in root.commands.items():
        assert f">rivercal {name}<a class=\"headerlink\"" in cli, name
        for sub in getattr(command, "commands", {}):
            assert f">rivercal {name} {sub}<a class=\"headerlink\"" in cli, f"{name} {sub}"
    schemas = (site / "reference" / "schemas.html").read_text(encoding="utf-8")
    for kind in ("case", "model"):
        schema = json.loads((site / "_downloads").glob(f"*/{kind}.schema.json").__next__().read_text())
        for name in schema["$defs"]:
            assert f'id="{kind}-schema-{name.lower()}"' in schemas, name
    store = (site / "reference" / "store.html").read_text(encoding="utf-8")
    for table in ("runs", "cycles", "estimates", "alerts", "observations", "forecasts", "model_states"):
        assert f"<code class=\"docutils literal notranslate\"><span class=\"pre\">{table}</span></code>" in store


def test_no_page_loads_anything_from_another_host(site: Path) -> None:
    asset = re.compile(r'<(?:script|link|img|iframe|source|video|audio)\b[^>]*\b(?:src|href)="(?:https?:)?//', re.I)
    css = re.compile(r"(?:url\(\s*['\"]?|@import\s+['\"])(?:https?:)?//", re.I)
    offenders = [str(p.relative_to(site)) for p in site.rglob("*.html") if asset.search(p.read_text(encoding="utf-8"))]
    offenders += [str(p.relative_to(site)) for p in site.rglob("*.css") if css.search(p.read_text(encoding="utf-8"))]
    assert not offenders
    assert (site / "_static" / "mathjax" / "tex-chtml.js").is_file()
