"""Read-only artefacts built once per test run and shared by its processes (the xdist workers).

Several modules start from the same expensive artefact (Dellen imported with its real-time forcing: about 2 s of
processor time each; the dependency map that ``rivercal analyse`` measures on dommel for Sparse DuD: about 2 s; a
short on-line replay whose store, report and summary two modules read: about 5 s).
:func:`artefact` builds it once, in the run's own folder (made by ``tests/conftest.py`` in the first process,
named by :data:`ENV_VAR`, inherited by the workers, removed when the run ends), under a file lock that the other
workers wait on; the others find it built. It is never kept from one run to the next, so a
test's result never depends on an earlier run. A test that changes the artefact works on a copy
(:func:`copy_of`).
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

#: The environment variable that names this run's folder of shared artefacts.
ENV_VAR = "RIVERCAL_TEST_ARTEFACTS"


def artefact(name: str, build: Callable[[Path], object]) -> Path:
    """The folder ``name`` of this run, made by ``build(folder)`` by the first test that asks for it.

    ``build`` writes into a folder that does not exist yet; it is renamed into place only when ``build``
    returned, so a build that failed leaves nothing, and the next test that asks builds it again (and fails
    with its own error). Without the folder of the run (a module imported outside pytest), a fresh
    temporary folder is built every time.
    """
    root = os.environ.get(ENV_VAR)
    if not root:
        folder = Path(tempfile.mkdtemp(prefix=f"rivercal-{name}-")) / name
        build(folder)
        return folder
    folder = Path(root) / name
    with open(Path(root) / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, also if this process dies
        if not folder.is_dir():
            scratch = Path(tempfile.mkdtemp(prefix=f".{name}-", dir=root))
            try:
                build(scratch / name)
                (scratch / name).rename(folder)
            finally:
                shutil.rmtree(scratch, ignore_errors=True)
    return folder


def copy_of(name: str, build: Callable[[Path], object], destination: Path) -> Path:
    """A copy of the artefact ``name`` (see :func:`artefact`) at ``destination``, for a test that changes it."""
    shutil.copytree(artefact(name, build), destination)
    return destination


def _import_dellen(folder: Path) -> None:
    from tests.cli import rivercal
    from tests.shared_data import shared_model

    source = shared_model("dhydro-dellen")
    folder.mkdir()
    run = rivercal("import", "dhydro", str(source / "dflowfm" / "Flow1D.mdu"), "--out", str(folder / "case"),
                   "--realtime", str(source / "rr_to_flow.nc"), "--realtime", str(source / "rtc_to_flow.nc"), "--json")
    assert run.returncode == 0, run.stderr
    (folder / "summary.json").write_text(run.stdout, encoding="utf-8")


def dellen(destination: Path) -> Path:
    """The shared D-HYDRO model Dellen imported with its two exchange files (``rivercal import dhydro
    ../shared/data/dhydro-dellen/dflowfm/Flow1D.mdu --realtime rr_to_flow.nc --realtime rtc_to_flow.nc``, run once
    per test run in this process, through :mod:`tests.cli`), copied to ``destination``: the case folder."""
    shutil.copytree(artefact("dellen-realtime", _import_dellen) / "case", destination)
    return destination


def dellen_summary() -> dict:
    """The JSON summary that the import of :func:`dellen` printed."""
    return json.loads((artefact("dellen-realtime", _import_dellen) / "summary.json").read_text(encoding="utf-8"))


#: The command whose dependency map :func:`dommel_dependency_map` shares (its ``--out`` folder is the artefact).
ANALYSE_FA_F1_FL_W2 = ("analyse", "dommel", "--params", "FA,F1,FL,W2", "--what", "identifiability", "--workers", "2",
                       "--quiet")


def _analyse_dommel(folder: Path) -> None:
    from tests.cli import rivercal

    analysed = rivercal(*ANALYSE_FA_F1_FL_W2, "--out", str(folder))
    assert analysed.returncode == 0, analysed.stderr


def dommel_dependency_map() -> Path:
    """``dependency.csv`` that :data:`ANALYSE_FA_F1_FL_W2` (``rivercal analyse dommel --params FA,F1,FL,W2 --what
    identifiability``) writes, run once per test run (in this process, through :mod:`tests.cli`); read-only."""
    return artefact("analyse-dommel-FA-F1-FL-W2", _analyse_dommel) / "dependency.csv"


#: The run's name in :data:`PIFG_REPLAY`.
PIFG_RUN = "pi-fg"
#: The short PI-Fg replay of dommel (two daily cycles after the friction changed 16 -> 25 m^(1/3)/s, a 3-day window)
#: whose store, report and summary :func:`pifg_replay` shares; ``--db`` and ``--out`` are added.
PIFG_REPLAY = ("online", "dommel", "--scenario", "PI-Fg", "--from", "2010-11-09", "--to", "2010-11-10", "--window",
               "3D", "--run", PIFG_RUN, "--workers", "2", "--assimilate", "parameters", "--json")
#: Stands for the artefact's folder in its stored summary (built elsewhere, then renamed into place).
_FOLDER = "{artefact folder}"


def _replay_pifg(folder: Path) -> None:
    from tests.cli import rivercal

    folder.mkdir()
    run = rivercal(*PIFG_REPLAY, "--db", str(folder / "run.sqlite"), "--out", str(folder / "report"))
    assert run.returncode == 0, run.stderr
    (folder / "summary.json").write_text(run.stdout.replace(str(folder), _FOLDER), encoding="utf-8")


def pifg_replay(destination: Path | None = None) -> tuple[Path, dict]:
    """:data:`PIFG_REPLAY` run once per test run (in this process, through :mod:`tests.cli`): its folder
    (``run.sqlite``, ``report/``) and its JSON summary, whose file names point into that folder. Read-only; with
    ``destination``, a copy there (for a test that writes to the store)."""
    folder = artefact("online-pifg", _replay_pifg) if destination is None else copy_of("online-pifg", _replay_pifg,
                                                                                        destination)
    text = (folder / "summary.json").read_text(encoding="utf-8")
    return folder, json.loads(text.replace(_FOLDER, str(folder)))
