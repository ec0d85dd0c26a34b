"""Shared fixtures and helpers for the test suite."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

from rivercal.case import case_from_dict
from rivercal.hydrology.hupsel import ENV_VAR as HUPSEL_ENV_VAR
from rivercal.models.spinups import ENV_VAR as CACHE_ENV_VAR
from tests.run_artefacts import ENV_VAR as ARTEFACTS_ENV_VAR

#: The repository's root folder.
REPOSITORY = Path(__file__).resolve().parents[1]
#: The shared data (GPL/LGPL data sets, never copied into the repository) lie beside the repository, as
#: CI lays them out: ``../shared`` from the repository root.
SHARED_DATA = REPOSITORY.parent / "shared" / "data"
#: Set (by ``.ci/run``) to make tests that need the Hupsel data fail instead of skip without them.
REQUIRE_HUPSEL = "RIVERCAL_REQUIRE_HUPSEL"

# Property tests draw the same examples on every run, so CI is reproducible; explore new ones locally with
# HYPOTHESIS_PROFILE=explore (random draws, remembered failures).
settings.register_profile("reproducible", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "reproducible"))


def hupsel_location() -> tuple[Path, str]:
    """Where the tests look for ``PEQ_Hupsel.dat``, and why there."""
    if os.environ.get(HUPSEL_ENV_VAR):
        return Path(os.environ[HUPSEL_ENV_VAR]).expanduser(), f"${HUPSEL_ENV_VAR}"
    return SHARED_DATA / "walrus-hupsel-hourly" / "PEQ_Hupsel.dat", "../shared beside the repository"


def hupsel_missing() -> str | None:
    """Why the Hupsel Brook data cannot be read, or None when they can."""
    path, origin = hupsel_location()
    if path.is_file():
        return None
    return (f"the Hupsel Brook data (WALRUS demo, GPL-3, never copied into the repository) are not at {path} "
            f"({origin}); put the shared data beside the repository (../shared/data/walrus-hupsel-hourly/"
            f"PEQ_Hupsel.dat from the repository root, as CI clones it) or set {HUPSEL_ENV_VAR} to the file")


#: Where this run's spin-up cache and its shared artefacts lie (set in the first process only).
_CACHE_KEY = pytest.StashKey[tuple[str, str]]()


def pytest_configure(config: pytest.Config) -> None:
    """One spin-up cache for this run, fresh, shared by its workers and the processes they start; and one
    folder for the read-only artefacts that several modules start from (:mod:`tests.run_artefacts`).

    Set in the first process (the workers and every command a test starts inherit them), never the user's own
    cache: what one run computed never reaches another, and a test's result never depends on an earlier run.
    """
    if not hasattr(config, "workerinput"):
        folders = tempfile.mkdtemp(prefix="rivercal-test-cache-"), tempfile.mkdtemp(prefix="rivercal-test-artefacts-")
        config.stash[_CACHE_KEY] = folders
        os.environ[CACHE_ENV_VAR], os.environ[ARTEFACTS_ENV_VAR] = folders


def pytest_unconfigure(config: pytest.Config) -> None:
    for folder in config.stash.get(_CACHE_KEY, ()):
        shutil.rmtree(folder, ignore_errors=True)


def pytest_sessionstart(session: pytest.Session) -> None:
    """With ``RIVERCAL_REQUIRE_HUPSEL`` set (CI), stop at once, with the reason, when the Hupsel data are missing."""
    if os.environ.get(REQUIRE_HUPSEL) and (reason := hupsel_missing()):
        pytest.exit(f"{REQUIRE_HUPSEL} is set but {reason}", returncode=pytest.ExitCode.USAGE_ERROR)


#: The longest modules (the SIGKILL replays on both backends, about 2 min on a loaded host; the documentation build),
#: started before all others so that neither of the two workers ends the suite alone with one of them.
LONGEST = ("tests/e2e/test_online_kills.py", "tests/e2e/test_docs_site.py")
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run the longest modules first, then those that hold slow tests, then the rest, each module's tests in order.

    ``make test`` distributes whole modules (``--dist loadfile --no-loadscope-reorder``) in this order to whichever
    worker is free: a module's shared fixtures (a documentation build, a reference replay, an imported model, a
    twin's truth) are made once in the run, never again on a second worker that took some of its tests, and the
    long end-to-end runs overlap with the many short modules instead of one worker finishing the suite alone with
    the last long run while the other waits.
    """
    slow = {item.path for item in items if item.get_closest_marker("slow") is not None}
    longest = [REPOSITORY / name for name in LONGEST]

    def rank(item: pytest.Item) -> tuple[int, int]:
        if item.path in longest:
            return 0, longest.index(item.path)
        return (1 if item.path in slow else 2), 0

    items.sort(key=rank)


@pytest.fixture(scope="session")
def hupsel_file() -> Path:
    """``PEQ_Hupsel.dat`` (see :func:`hupsel_location`); the test is skipped with the reason when it is missing."""
    reason = hupsel_missing()
    if reason is not None:
        pytest.skip(reason)
    return hupsel_location()[0]


def channel_case(
    *,
    length: float = 5000.0,
    dx: float = 100.0,
    slope: float = 1e-4,
    profile: dict | None = None,
    friction: dict | None = None,
    inflow: float = 10.0,
    downstream: dict | None = None,
    days: float = 2.0,
    depth: float = 1.0,
    engine: dict | None = None,
    stations: list | None = None,
    weirs: list | None = None,
) -> dict:
    """A single prismatic channel from ``up`` (discharge boundary) to ``down`` as a case dict."""
    profile = profile or {"id": "p", "type": "rectangular", "width": 10.0}
    end_day = 1 + int(days)
    hours = round((days - int(days)) * 24)
    return {
        "case": {"name": "channel", "start": "2020-01-01T00:00:00Z",
                 "end": f"2020-01-{end_day:02d}T{hours:02d}:00:00Z"},
        "engine": {"dt": 60.0, **(engine or {})},
        "initial": {"depth": depth},
        "friction": friction or {"type": "strickler", "value": 30.0},
        "profiles": [profile],
        "nodes": [{"id": "up", "x": 0.0, "y": 0.0}, {"id": "down", "x": length, "y": 0.0}],
        "branches": [{
            "id": "B", "from_node": "up", "to_node": "down", "length": length, "dx": dx,
            "cross_sections": [
                {"chainage": 0.0, "profile": profile["id"], "bed_level": slope * length},
                {"chainage": length, "profile": profile["id"], "bed_level": 0.0},
            ],
        }],
        "weirs": weirs or [],
        "boundaries": [
            {"id": "Qin", "node": "up", "type": "discharge", "value": inflow},
            downstream or {"id": "hout", "node": "down", "type": "level", "value": depth},
        ],
        "stations": stations or [{"id": "mid", "branch": "B", "chainage": length / 2, "quantities": ["h", "Q"]}],
    }


@pytest.fixture
def make_case(tmp_path: Path):
    """Build a validated Case from a dict (series files, if any, relative to a temp folder)."""

    def _make(data: dict):
        return case_from_dict(data, tmp_path)

    return _make


#: The official Delft-FEWS PI schemas (LGPL, kept beside the repository as on CI, never copied into it).
PI_SCHEMA_DIR = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "fews-pi-schemas"


@pytest.fixture(scope="session")
def compiled_engine() -> dict:
    """The time loop compiled into numba's cache before a test times subprocesses of rivercal.

    ``make test`` compiles it before the suite; a test run on its own with a cold cache would otherwise
    see its first subprocess take minutes longer than the next ones. Each variant's readiness.
    """
    from rivercal.engine.warmup import compile_engine

    return compile_engine()


@pytest.fixture(scope="session")
def pi_schema():
    """``pi_schema("pi_timeseries.xsd")``: an :class:`xmlschema.XMLSchema` read from ../shared/data/fews-pi-schemas.

    Fails (never skips) when the folder is missing: the PI files rivercal writes are checked against them.
    """
    import xmlschema

    cache: dict[str, object] = {}

    def load(name: str):
        path = PI_SCHEMA_DIR / name
        if not path.is_file():
            pytest.fail(f"the Delft-FEWS PI schema {name} is missing: expected {path} (the folder "
                        "../shared/data/fews-pi-schemas beside the repository)")
        if name not in cache:
            cache[name] = xmlschema.XMLSchema(str(path))
        return cache[name]

    return load


def assert_valid_pi(schema, path) -> None:
    """Fail with every schema error of a PI file (not only the first)."""
    errors = [f"{e.path}: {e.reason}" for e in schema.iter_errors(str(path))]
    assert not errors, f"{path} does not validate against {Path(schema.url).name}:\n" + "\n".join(errors[:10])


# -- a real PostgreSQL server (one per test process), a fresh database per test -----------------------------


@pytest.fixture(scope="session")
def postgres_server():
    from tests.postgres import PostgresServer, missing

    why = missing()
    if why is not None:
        pytest.fail(f"the PostgreSQL store tests need a server: {why}")
    server = PostgresServer().start()
    yield server
    server.stop()


@pytest.fixture
def pg_url(postgres_server) -> str:
    """The URL of a new, empty database on the test server."""
    return postgres_server.new_database()
