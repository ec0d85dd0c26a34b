"""Compiled kernels kept per user and version of their sources: another installation of the same sources loads them.

The end-to-end test copies rivercal's package to two folders, as two clones or virtual environments would
hold it, and calls a small kernel of the rainfall-runoff model in a fresh process of each: the first
compiles it, the second (other path, same sources) loads it from the user's folder, and a change in
another file of the same folder names a new version folder, compiled again. numba's own counters tell a
compile from a load.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

import rivercal
from rivercal import _kernel_cache
from rivercal._kernel_cache import KEEP, kernel_folder

PACKAGE = Path(rivercal.__file__).resolve().parent

SCRIPT = """
import json
from rivercal._kernel_cache import kernel_folder
from rivercal.hydrology import _kernels
w = _kernels.wetness(2.5, 10.0)
stats = _kernels.wetness.stats
print(json.dumps({"folder": str(kernel_folder(_kernels.__file__)), "value": w,
                  "hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values())}))
"""


def _clone(where: Path) -> Path:
    """A copy of rivercal's package (sources only) under ``where``."""
    shutil.copytree(PACKAGE, where / "rivercal", ignore=shutil.ignore_patterns("__pycache__"))
    return where


def _call(clone: Path, cache: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update(PYTHONPATH=str(clone), XDG_CACHE_HOME=str(cache))
    run = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, cwd=clone,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout)


def test_another_copy_of_the_same_sources_loads_the_kernels_and_a_changed_one_compiles_them(tmp_path) -> None:
    cache = tmp_path / "cache"
    first = _call(_clone(tmp_path / "a"), cache)
    assert (first["hits"], first["misses"]) == (0, 1)
    folder = Path(first["folder"])
    assert folder.parent == cache / "rivercal" / "kernels" and folder.name.startswith("hydrology-")
    assert list(folder.glob("_kernels.wetness-*.nbi")), "nothing kept in the user's folder"
    assert not list((tmp_path / "a").rglob("*.nbi")), "the kernel was kept beside the copy's sources too"

    other = _clone(tmp_path / "b")
    second = _call(other, cache)
    assert (second["hits"], second["misses"]) == (1, 0), "another copy of the same sources compiled again"
    assert second["folder"] == first["folder"] and second["value"] == first["value"]

    with (other / "rivercal" / "hydrology" / "metrics.py").open("a") as f:
        f.write("\n# a change in another file of the folder\n")
    third = _call(other, cache)
    assert (third["hits"], third["misses"]) == (0, 1)
    assert Path(third["folder"]) != folder and Path(third["folder"]).parent == folder.parent


def test_numba_cache_dir_and_files_outside_the_package_folders_are_left_to_numba(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    engine_file = PACKAGE / "engine" / "kernels" / "timeloop.py"
    folder = kernel_folder(engine_file)
    assert folder.parent == tmp_path / "rivercal" / "kernels" and folder.name.startswith("engine.kernels-")
    assert kernel_folder(PACKAGE / "engine" / "kernels" / "solver.py") == folder
    assert kernel_folder(PACKAGE / "engine" / "simulator.py").name.startswith("engine-")  # another folder
    assert kernel_folder(PACKAGE / "_time.py") is None          # not in a folder of the package
    assert kernel_folder(tmp_path / "elsewhere.py") is None     # not rivercal's
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    assert kernel_folder(engine_file) is None


def test_only_the_most_recently_used_versions_are_kept(tmp_path) -> None:
    now = time.time()
    versions = [tmp_path / f"engine.kernels-{i:016x}" for i in range(KEEP + 2)]
    for age, version in enumerate(versions):
        version.mkdir()
        os.utime(version, (now - 3600 * (age + 1), now - 3600 * (age + 1)))
    hydrology = tmp_path / "hydrology-0000000000000000"
    hydrology.mkdir()
    os.utime(hydrology, (now - 10**6, now - 10**6))
    oldest = versions[-1]
    _kernel_cache._in_use.__wrapped__(oldest)      # used now: it becomes the most recent
    kept = sorted(p.name for p in tmp_path.glob("engine.kernels-*"))
    assert kept == sorted(v.name for v in [oldest, *versions[: KEEP - 1]])
    assert hydrology.is_dir(), "another folder's version was removed"


def test_a_folder_that_cannot_be_written_is_reported_once_and_numba_places_the_kernels(monkeypatch, tmp_path,
                                                                                       caplog) -> None:
    from rivercal.hydrology import _kernels

    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    locator = _kernel_cache._locator_class()
    with caplog.at_level(logging.WARNING, logger="rivercal._kernel_cache"):
        for _ in range(2):
            assert locator.from_function(_kernels.wetness.py_func, _kernels.__file__) is None
    warnings = [r for r in caplog.records if "cannot be kept" in r.getMessage()]
    assert len(warnings) == 1 and str(blocked) in warnings[0].getMessage()


@pytest.mark.parametrize("kernel", ["engine", "hydrology"])
def test_rivercal_kernels_use_the_locator(kernel) -> None:
    """The engine's and the rainfall-runoff model's kernels are placed by rivercal's locator in this process."""
    if kernel == "engine":
        from rivercal.engine.kernels.timeloop import run as dispatcher
    else:
        from rivercal.hydrology._kernels import run_walrus as dispatcher
    locator = dispatcher._cache._impl.locator
    expected = kernel_folder(dispatcher.py_func.__code__.co_filename)
    assert expected is not None and Path(locator.get_cache_path()) == expected


def test_where_no_folder_can_be_written_the_process_compiles_the_kernels_for_itself(tmp_path) -> None:
    """A read-only installation run by a user whose home cannot be written: numba said "cannot cache function".

    The copy's ``hydrology/__pycache__`` is a file (numba cannot keep the kernel beside its source) and the
    home and cache folders lie below a file (neither rivercal's folder nor numba's own can be made): the kernel
    still compiles and runs, with one warning that says how to keep it, and nothing is left behind.
    """
    clone = _clone(tmp_path / "a")
    (clone / "rivercal" / "hydrology" / "__pycache__").write_text("not a folder")
    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")
    private = tmp_path / "tmp"
    private.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update(PYTHONPATH=str(clone), XDG_CACHE_HOME=str(blocked / "cache"), HOME=str(blocked / "home"),
               TMPDIR=str(private), PYTHONDONTWRITEBYTECODE="1")
    script = "import logging; logging.basicConfig(level=logging.WARNING)\n" + SCRIPT  # as the command line does
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=clone,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout)
    assert (out["hits"], out["misses"]) == (0, 1)
    from rivercal.hydrology import _kernels

    assert out["value"] == pytest.approx(_kernels.wetness.py_func(2.5, 10.0), rel=1e-12)
    assert run.stderr.count("this process compiles them for itself") == 1
    assert "XDG_CACHE_HOME" in run.stderr and "RuntimeError" not in run.stderr
    assert list(private.iterdir()) == []  # the private folder ended with the process
