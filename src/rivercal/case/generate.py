"""Synthetic lowland networks of any size, written as a case folder (``rivercal case generate``).

A water board's network is many small catchments, each a tree of weir-controlled streams draining to
one outlet, with side channels that split off and join again. :func:`generate_case` draws such a
network from a seed:

- **catchments** of about :data:`CATCHMENT_KM` km of stream, each a tree grown upstream from its
  outlet on a trunk canal that collects them all and ends at a held level (a pumping station or the
  sea; 0.5 m AD): every branch 2-5 km long ends upstream either in a confluence of two branches or in a source
  (a discharge boundary with the base flow of a ditch system); about one branch in eight between two confluences has a
  parallel side channel between the same two nodes (a bifurcation and a confluence: a loop);
- **beds** falling 0.3-0.5 m per km towards the outlet; trapezoidal profiles (side slope 1.5, 2.5 m
  deep) whose bottom width grows with the square root of the stream length upstream (1.5-14 m); the
  trunk is 20 m plus 2 m per catchment wide, 6 m deep, its bed at -3 m AD;
- **weirs** every ~1 km with the crest 0.9 m above the bed, as wide as the bottom; a culvert on every
  seventh branch; a lateral inflow per branch;
- **stations** at every outlet weir, every tenth weir and the first weir of each region (levels either
  side and the discharge), and on each trunk reach (level and discharge);
- **parameters** ``FA`` (global friction) and ``F1`` … ``F20``: the friction of 20 regions (branches in
  order of growth, in 20 contiguous groups), for calibration tests at scale;
- **forcing**: three weeks of hourly inflows, a base flow and two storms whose timing differs by
  catchment (storm shape as the packaged ``synthetic`` case).

The case validates like any other (:func:`rivercal.case.load_case`). The number of calculation points is
close to the ``points`` asked for (dx = 100 m; structures add a few); the exact count is what the engine
compiles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from pydantic import ValidationError

from rivercal.case.schema import EngineSettings

__all__ = ["CATCHMENT_KM", "GeneratedCase", "generate_case"]

#: Stream length of one catchment, km (a larger network has more catchments, not larger ones).
CATCHMENT_KM = 400.0
_DX = 100.0
_START = pd.Timestamp("2020-01-01T00:00:00Z")
_DAYS = 21
_REGIONS = 20
_CLASSES = 3  # lateral inflow classes per catchment (small, medium, large streams)
_TRUNK_DX = 5000.0  # length of a trunk canal reach between two catchment outlets, m
_TRUNK_BED = -3.0  # bed of the trunk canal, m AD
_TRUNK_LEVEL = 0.5  # level held at the trunk's end (the pumping station or the sea), m AD
_OUTPUT_INTERVAL = 3600.0  # s: hourly station series
_HEADER = "# Generated lowland network: rivercal case generate"  # first line of a generated case.toml


@dataclass
class _Branch:
    id: str
    up: str
    down: str
    length: float
    bed_up: float
    bed_down: float
    width: float
    catchment: int
    side: bool = False
    weirs: list[tuple[str, float, float]] = field(default_factory=list)  # id, chainage, crest


@dataclass(frozen=True)
class GeneratedCase:
    """What :func:`generate_case` wrote: the folder and the network's size."""

    path: Path
    catchments: int
    branches: int
    length_km: float
    weirs: int
    culverts: int
    laterals: int
    stations: int


def _grow(rng: np.random.Generator, km: float, c: int, origin: tuple[float, float],
          nodes: dict[str, tuple[float, float]], next_id: list[int]) -> list[_Branch]:
    """One catchment: a tree of about ``km`` km grown upstream from its outlet node."""
    outlet = f"O{c}"
    nodes[outlet] = origin
    branches: list[_Branch] = []
    open_nodes = [(outlet, 0.0, math.pi / 2)]  # node, bed level (m AD), direction upstream (rad)
    total = 0.0
    while open_nodes:
        down, bed_down, heading = open_nodes.pop(0)
        children = 1 if down == outlet else (2 if total < km * 1000.0 else 0)
        for k in range(children):
            length = float(rng.uniform(2000.0, 5000.0))
            angle = heading + (0.0 if children == 1 else (-0.6 if k == 0 else 0.6)) + float(rng.normal(0, 0.2))
            x0, y0 = nodes[down]
            up = f"N{next_id[0]}"
            next_id[0] += 1
            nodes[up] = (round(x0 + length * 0.8 * math.cos(angle), 1), round(y0 + length * 0.8 * math.sin(angle), 1))
            bed_up = round(bed_down + length * float(rng.uniform(3e-4, 5e-4)), 3)
            branches.append(_Branch(f"B{next_id[0]}", up, down, round(length, 1), bed_up, bed_down, 0.0, c))
            total += length
            open_nodes.append((up, bed_up, angle))
    return branches


def _widths(branches: list[_Branch]) -> None:
    """Bottom width from the stream length upstream of each branch's downstream end."""
    upstream: dict[str, float] = {}
    for b in reversed(branches):  # grown downstream-first: reversed, every upstream branch comes first
        upstream[b.down] = upstream.get(b.down, 0.0) + upstream.get(b.up, 0.0) + b.length
    for b in branches:
        km = (upstream.get(b.up, 0.0) + b.length) / 1000.0
        b.width = float(min(14.0, max(1.5, round(2.0 * (0.75 + 0.3 * math.sqrt(km))) / 2.0)))


def _event(hours: np.ndarray, peak: float, width: float) -> np.ndarray:
    x = np.clip((hours - peak) / width + 1.0, 0.0, None)
    return x**2 * np.exp(2.0 * (1.0 - x))


def divides_the_hour(dt: float) -> bool:
    """Whether a time step ``dt`` (s) suits the generated case's hourly output (the case schema's own rule)."""
    try:
        EngineSettings(dt=dt, output_interval=_OUTPUT_INTERVAL)
    except ValidationError:
        return False
    return True


def generate_case(out: str | Path, points: int, seed: int = 0, name: str | None = None,
                  dt: float = 60.0) -> GeneratedCase:
    """Write a generated lowland network of about ``points`` calculation points as a case folder.

    Parameters
    ----------
    out
        The case folder to write (created; ``case.toml``, ``forcing.csv`` and ``README.md`` in it are
        replaced).
    points
        Calculation points wanted (at least 100).
    seed
        Seed of the random network (the same seed and points give the same files).
    name
        Case name (default ``generated-<points>-<seed>``).
    dt
        The engine's time step, s (``[engine] dt``; a divisor of the hourly output interval). 60 s keeps
        the levels at the stations within millimetres of a finer step; a board's forecasting model often
        runs at 300 s, which is about four times faster and differs from 60 s by centimetres at weirs
        that change regime while a flood rises (see the cluster guide).

    Raises
    ------
    ValueError
        For fewer than 100 points, a negative seed or a time step that does not divide 3600 s.
    FileExistsError
        If ``out`` holds a ``case.toml`` that the generator did not write (a generated one is replaced).
    """
    if points < 100:
        raise ValueError(f"points must be at least 100, got {points}")
    if seed < 0:
        raise ValueError(f"seed must not be negative, got {seed}")
    if not divides_the_hour(dt):
        raise ValueError(f"dt must be a divisor of 3600 s (the output interval), got {dt}")
    existing = Path(out) / "case.toml"
    if existing.is_file() and not existing.read_text(encoding="utf-8", errors="replace").startswith(_HEADER):
        raise FileExistsError(f"{existing}: a case the generator did not write; give another folder")
    rng = np.random.default_rng(seed)
    km = points * _DX / 1000.0 * 0.86  # a branch of n dx has n + 1 points; each structure adds about 1.5
    n_catchments = max(1, math.ceil(km / CATCHMENT_KM))
    nodes: dict[str, tuple[float, float]] = {}
    next_id = [0]
    branches: list[_Branch] = []
    for c in range(n_catchments):
        branches += _grow(rng, km / n_catchments * 0.93, c, (c * _TRUNK_DX, 0.0), nodes, next_id)
    side = []
    confluences = {b.down for b in branches}
    for b in branches:  # a side channel between two confluences (never at a source, whose node ends the network)
        if b.down[0] == "N" and b.up in confluences and rng.random() < 1 / 8:
            side.append(_Branch(b.id + "s", b.up, b.down, round(b.length * 1.1, 1), b.bed_up, b.bed_down, 0.0,
                                b.catchment, side=True))
    branches += side
    _widths(branches)
    for b in side:
        b.width = max(1.5, b.width / 2)
    name = name or f"generated-{points}-{seed}"
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    forcing = _forcing(rng, n_catchments)
    forcing.to_csv(out / "forcing.csv", float_format="%.4f")
    args = f"--points {points} --seed {seed}" + ("" if dt == 60.0 else f" --dt {dt:g}")
    text, counts = _case_toml(name, branches, nodes, n_catchments, rng, args, dt)
    (out / "case.toml").write_text(text, encoding="utf-8")
    total_km = sum(b.length for b in branches) / 1000.0
    (out / "README.md").write_text(
        f"# {name}\n\nGenerated by `rivercal case generate {args}` (rivercal.case.generate): "
        f"{n_catchments} lowland catchments, {len(branches)} branches ({total_km:.0f} km), "
        f"{counts['weirs']} weirs, {counts['culverts']} culverts, {counts['laterals']} laterals, "
        f"{counts['stations']} stations; synthetic storms.\n", encoding="utf-8")
    return GeneratedCase(path=out, catchments=n_catchments, branches=len(branches),
                         length_km=round(total_km, 1), **counts)


def _forcing(rng: np.random.Generator, n_catchments: int) -> pd.DataFrame:
    """Hourly inflows, m³/s: a source's base flow and, per catchment and class, a lateral per km of stream."""
    times = pd.date_range(_START, periods=_DAYS * 24 + 1, freq="h")
    hours = np.arange(times.size, dtype=float)
    data = {"Q_source": 0.03 + 0.1 * _event(hours, 100.0, 18.0)}
    for c in range(n_catchments):
        lag = float(rng.uniform(-12.0, 12.0))
        storm = _event(hours, 100.0 + lag, 18.0) + 0.6 * _event(hours, 300.0 + lag, 24.0)
        for k in range(_CLASSES):
            data[f"L{c}_{k}"] = 3.5 * (0.002 + 0.02 * storm) * (1 + k)  # a branch of 3.5 km of that class
    frame = pd.DataFrame(data, index=times.strftime("%Y-%m-%dT%H:%M:%SZ"))
    frame.index.name = "time"
    return frame


def _case_toml(name: str, branches: list[_Branch], nodes: dict[str, tuple[float, float]], n_catchments: int,
               rng: np.random.Generator, args: str, dt: float) -> tuple[str, dict[str, int]]:
    end = _START + pd.Timedelta(days=_DAYS)
    lines = [f"{_HEADER} {args}", "[case]",
             f'name = "{name}"', f'description = "Generated lowland network, {len(branches)} branches"',
             f'start = "{_START:%Y-%m-%dT%H:%M:%SZ}"', f'end = "{end:%Y-%m-%dT%H:%M:%SZ}"', "",
             "[engine]", f"dt = {float(dt)}", f"output_interval = {_OUTPUT_INTERVAL}", "",
             "[initial]", "depth = 1.0", "spinup = 48.0", "",
             "[friction]", 'type = "strickler"', "value = 25.0", ""]
    for w in sorted({b.width for b in branches}):
        lines += ["[[profiles]]", f'id = "t{_pid(w)}"', 'type = "trapezoidal"', f"bottom_width = {w:g}",
                  "side_slope = 1.5", "height = 2.5", ""]
    for nid, (x, y) in nodes.items():
        lines += ["[[nodes]]", f'id = "{nid}"', f"x = {x}", f"y = {y}", ""]
    trunk_width = 20.0 + 2.0 * n_catchments
    lines += ["[[profiles]]", 'id = "trunk"', 'type = "trapezoidal"', f"bottom_width = {trunk_width:g}",
              "side_slope = 2.0", "height = 6.0", "", "[[nodes]]", 'id = "END"', f"x = {n_catchments * _TRUNK_DX}",
              "y = 0.0", ""]
    for c in range(n_catchments):  # the trunk canal that collects every catchment's outflow
        down = f"O{c + 1}" if c + 1 < n_catchments else "END"
        lines += ["[[branches]]", f'id = "T{c}"', f'from_node = "O{c}"', f'to_node = "{down}"',
                  f"length = {_TRUNK_DX:g}", f"dx = {2 * _DX:g}", "cross_sections = [",
                  f'  {{ chainage = 0.0, profile = "trunk", bed_level = {_TRUNK_BED} }},',
                  f'  {{ chainage = {_TRUNK_DX:g}, profile = "trunk", bed_level = {_TRUNK_BED} }},', "]", ""]
    weirs, culverts, laterals, stations, regions = [], [], [], [], []
    for i, b in enumerate(branches):
        lines += ["[[branches]]", f'id = "{b.id}"', f'from_node = "{b.up}"', f'to_node = "{b.down}"',
                  f"length = {b.length}", f"dx = {_DX:g}", "cross_sections = [",
                  f'  {{ chainage = 0.0, profile = "t{_pid(b.width)}", bed_level = {b.bed_up} }},',
                  f'  {{ chainage = {b.length}, profile = "t{_pid(b.width)}", bed_level = {b.bed_down} }},', "]", ""]
        chain = 500.0 + float(rng.uniform(0.0, 300.0))
        while chain < b.length - 400.0:
            bed = b.bed_up + (b.bed_down - b.bed_up) * chain / b.length
            weirs.append((f"W{len(weirs) + 1}", b.id, round(chain, 1), round(bed + 0.9, 3), b.width))
            b.weirs.append(weirs[-1][:2] + weirs[-1][2:3])
            chain += float(rng.uniform(800.0, 1200.0))
        if i % 7 == 3 and b.length > 1500.0:
            bed = b.bed_up + (b.bed_down - b.bed_up) * 250.0 / b.length
            culverts.append((f"K{len(culverts) + 1}", b.id, 250.0, round(bed + 0.05, 3), 1.0 if b.width < 4 else 1.6))
        klass = 0 if b.width < 3 else (1 if b.width < 7 else 2)
        laterals.append((f"L{len(laterals) + 1}", b.id, round(b.length - 200.0, 1), f"L{b.catchment}_{klass}"))
        regions.append(min(_REGIONS - 1, i * _REGIONS // len(branches)))
    for wid, bid, ch, crest, width in weirs:
        lines += ["[[weirs]]", f'id = "{wid}"', f'branch = "{bid}"', f"chainage = {ch}", f"crest_level = {crest}",
                  f"crest_width = {width:g}", "discharge_coefficient = 1.0", ""]
    for kid, bid, ch, invert, diameter in culverts:
        lines += ["[[culverts]]", f'id = "{kid}"', f'branch = "{bid}"', f"chainage = {ch}", 'shape = "circular"',
                  f"diameter = {diameter}", f"invert_level = {invert}", "length = 20.0", ""]
    ups = {b.up for b in branches}
    downs = {b.down for b in branches}
    for n in sorted(ups - downs):  # sources: one branch starts there, none ends there
        lines += ["[[boundaries]]", f'id = "Q{n}"', f'node = "{n}"', 'type = "discharge"',
                  'series = { file = "forcing.csv", column = "Q_source" }', ""]
    lines += ["[[boundaries]]", 'id = "end"', 'node = "END"', 'type = "level"', f"value = {_TRUNK_LEVEL}", ""]
    for lid, bid, ch, column in laterals:
        lines += ["[[laterals]]", f'id = "{lid}"', f'branch = "{bid}"', f"chainage = {ch}",
                  f'series = {{ file = "forcing.csv", column = "{column}" }}', ""]
    first_weir = {}
    for b in branches:
        if b.weirs and b.down.startswith("O"):
            stations.append(b.weirs[-1][0])
    point_stations = [f"T{c}" for c in range(n_catchments)]
    for k, (wid, *_rest) in enumerate(weirs):
        if k % 10 == 0:
            stations.append(wid)
    for b, region in zip(branches, regions, strict=True):
        if b.weirs and region not in first_weir:
            first_weir[region] = b.weirs[0][0]
            stations.append(b.weirs[0][0])
    stations = list(dict.fromkeys(stations))
    for sid in stations:
        lines += ["[[stations]]", f'id = "S{sid}"', f'structure = "{sid}"', 'quantities = ["h_up", "h_down", "Q"]', ""]
    for tid in point_stations:
        lines += ["[[stations]]", f'id = "S{tid}"', f'branch = "{tid}"', f"chainage = {_TRUNK_DX / 2:g}",
                  'quantities = ["h", "Q"]', ""]
    lines += ["[[parameters]]", 'name = "FA"', 'targets = ["friction:global"]', "min = 10.0", "max = 50.0",
              "initial = 25.0", "perturbation = 2.0", 'unit = "m^(1/3)/s"', ""]
    for r in range(_REGIONS):
        ids = [b.id for b, reg in zip(branches, regions, strict=True) if reg == r]
        if not ids:
            continue
        targets = ", ".join(f'"friction:branch:{i}"' for i in ids)
        lines += ["[[parameters]]", f'name = "F{r + 1}"', f"targets = [{targets}]", "min = 10.0", "max = 50.0",
                  "initial = 25.0", "perturbation = 2.0", 'unit = "m^(1/3)/s"', ""]
    lines += ["[calibration]", 'algorithm = "dud"', "", "[[windows]]", 'name = "week"',
              f'start = "{_START + pd.Timedelta(days=3):%Y-%m-%dT%H:%M:%SZ}"',
              f'end = "{_START + pd.Timedelta(days=10):%Y-%m-%dT%H:%M:%SZ}"', 'description = "the first storm"', ""]
    counts = {"weirs": len(weirs), "culverts": len(culverts), "laterals": len(laterals),
              "stations": len(stations) + len(point_stations)}
    return "\n".join(lines), counts


def _pid(width: float) -> str:
    return f"{width:g}".replace(".", "_")
