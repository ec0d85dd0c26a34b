"""Read-only artefacts built once per test run and shared by its processes (the xdist workers).

Several modules start from the same expensive artefact (Dellen imported with its real-time forcing: about 2 s of
processor time each). :func:`artefact` builds it once, in the run's own folder (made by ``tests/conftest.py`` in the
first process, named by :data:`ENV_VAR`, inherited by the workers, removed when the run ends), under a file lock
that the other workers wait on; the others find it built. It is never kept from one run to the next, so a
test's result never depends on an earlier run. A test that changes the artefact works on a copy
(:func:`copy_of`).
"""

from __future__ import annotations

import fcntl
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
    from rivercal.io.dhydro import ImportOptions, import_dhydro
    from tests.shared_data import shared_model

    source = shared_model("dhydro-dellen")
    import_dhydro(source / "dflowfm" / "Flow1D.mdu", folder,
                  ImportOptions(realtime=(source / "rr_to_flow.nc", source / "rtc_to_flow.nc")))


def dellen(destination: Path) -> Path:
    """The shared D-HYDRO model Dellen imported with its two exchange files (``rivercal import dhydro
    ../shared/data/dhydro-dellen/dflowfm/Flow1D.mdu --realtime rr_to_flow.nc --realtime rtc_to_flow.nc``),
    copied to ``destination``: the case folder."""
    return copy_of("dellen-realtime", _import_dellen, destination)
