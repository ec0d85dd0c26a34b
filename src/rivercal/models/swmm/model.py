"""EPA SWMM 5 behind the model contract, through swmm-toolkit (SWMM's own engine, not a re-implementation).

:class:`SwmmModel` runs an ``.inp`` file in this process: per run it writes a copy of the file with the
run's period, reporting step, quantities and hot-start files into a run folder, runs SWMM with the
toolkit's ``swmm_open``/``swmm_start``/``swmm_stride`` (silent, unlike ``swmm_run``), reads the station
series from the binary output and keeps SWMM's hotstart file as the state.

Quantities (SI units; the file must use ``FLOW_UNITS CMS``):

- ``friction:global`` (m^(1/3)/s): a Strickler k_s for every conduit (Manning n = 1/k_s instead of the
  file's n), the quantity of the embedded engine's global friction;
- ``friction:branch:<tag>`` (m^(1/3)/s): a Strickler k_s for the conduits tagged ``<tag>`` in ``[TAGS]``
  (the converter of :mod:`~rivercal.models.swmm.convert` tags conduits with their branch id);
- ``conduit:<id>.roughness`` (s/m^(1/3)): Manning n of one conduit (before the others: the most specific
  value wins, conduit over tag over global over the file);
- ``roughness:factor`` (-): multiplies every conduit's Manning n (after the values above);
- ``roughness:group:<tag>`` (-): multiplies the Manning n of the conduits tagged ``<tag>``;
- ``weir:<id>.crest_level`` (m, the model's datum): crest elevation of a weir (written as its crest
  height above the inlet node's invert, or as the elevation with ``LINK_OFFSETS ELEVATION``);
- ``orifice:<id>.setting`` (-, 0 closed … 1 open): set through the toolkit at the start of the run.

Stations: ``<station>.<quantity>`` → ``node:<id>`` (hydraulic head, m) or ``link:<id>`` (flow, m³/s).

Time: a cold-started run begins ``spinup`` hours before its ``start`` from the file's initial depths and
reports from there; a hot-started run begins at ``start`` from the state's hotstart file. The row at
``start`` of a hot-started run is read from SWMM after the hotstart file is applied. SWMM's binary output
holds single precision (≈ 1e-6 relative).

SWMM keeps its project in process globals: one run at a time per process (rivercal's evaluator uses
processes, so parallel calibrations work).

A run's input file holds of each ``[TIMESERIES]`` series only the points of its period (and the one before
and after it), so that SWMM does not read two months of hourly inflows to run one hour; the values SWMM
interpolates in the period are the same.

Optional capabilities (:mod:`rivercal.models.capabilities`):

- **perturbable forcing**: the inflows of ``[INFLOWS]`` (``inflow:<node>``, flow constituents), scaled by a
  factor per interval: a run is made of one SWMM run per interval, each with the inflows' scale factors
  (``Sfactor``) times its factors, hot-started from the one before;
- **state arrays**: the state's hotstart file (:mod:`~rivercal.models.swmm.hotstart`, SWMM's documented layout)
  read as the heads of the nodes (invert + depth, m) and the flows of the links (m³/s), and written back
  (the depths never below the invert); SWMM computes the nodes' volumes from the depths when a run starts;
- **variants**: a copy whose inflow series are multiplied by factor series (a twin's rain error).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import shutil
import tempfile
import time as _time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.models.capabilities import StateLayout, VariantInputs
from rivercal.models.contract import CalibrationSetup, ExternalRunError, FileState, Quantity, check_run, utc
from rivercal.models.swmm.hotstart import read_hotstart
from rivercal.models.swmm.inp import NODE_SECTIONS, InpFile, seconds, swmm_date, swmm_step
from rivercal.models.swmm.output import parse_element, read_swmm_output
from rivercal.results import SimulationResult

__all__ = ["SwmmModel", "SwmmRunError"]

log = logging.getLogger(__name__)

HOTSTART = "hotstart.hsf"
#: The sections of links, each row ``Name FromNode ToNode …`` (SWMM numbers links in the order they come).
LINK_SECTIONS = ("CONDUITS", "PUMPS", "ORIFICES", "WEIRS", "OUTLETS")


class SwmmRunError(ExternalRunError):
    """A SWMM run failed; names the run folder and SWMM's message."""

    what = "SWMM run"


class SwmmModel:
    """An EPA SWMM 5 model behind the model contract (module docstring).

    Parameters
    ----------
    inp
        The ``.inp`` file.
    stations
        ``<station>.<quantity>`` → ``node:<id>`` or ``link:<id>``.
    name
        Name of the model.
    start, end
        The model's period (UTC).
    output_interval
        Default interval of the series, s.
    spinup
        Hours a cold-started run begins before its start.
    calibration
        Parameters, windows and optimiser defaults that ship with the model.
    runs_dir
        Where run folders go (default: a temporary folder).

    Raises
    ------
    ValueError
        For a file that is not in SI flow units, or stations that name no object of the file.
    """

    def __init__(self, inp: str | Path | InpFile, stations: Mapping[str, str], *, name: str, start: Any, end: Any,
                 output_interval: float = 3600.0, spinup: float = 0.0,
                 calibration: CalibrationSetup | None = None, runs_dir: str | Path | None = None):
        self._inp = inp if isinstance(inp, InpFile) else InpFile.read(inp)
        self.inp_path = Path(self._inp.source)
        self.name = name
        self._start, self._end = utc(start), utc(end)
        self._interval = float(output_interval)
        self.spinup = float(spinup)
        self._calibration = calibration or CalibrationSetup()
        self.runs_dir = Path(runs_dir) if runs_dir is not None else None
        label = str(self.inp_path)
        units = (self._inp.option("FLOW_UNITS") or "CFS").upper()
        if units != "CMS":
            raise ValueError(f"{label}: [OPTIONS] FLOW_UNITS is {units}; rivercal needs SI units (CMS, m³/s)")
        self._dt = seconds(self._inp.option("ROUTING_STEP"), 20.0)
        tolerance = self._inp.option("HEAD_TOLERANCE")
        self._head_tolerance = float(tolerance) if tolerance else 0.0015
        self._elevation_offsets = (self._inp.option("LINK_OFFSETS") or "DEPTH").upper() == "ELEVATION"
        self._inverts = self._inp.node_inverts()
        self._conduits = {r.tokens[0]: float(r.tokens[4]) for r in self._inp.rows("CONDUITS")}
        self._weirs = {r.tokens[0]: (r.tokens[1], float(r.tokens[4])) for r in self._inp.rows("WEIRS")}
        self._orifices = [r.tokens[0] for r in self._inp.rows("ORIFICES")]
        self._groups = {tag: [c for c in ids if c in self._conduits] for tag, ids in self._inp.tags("Link").items()}
        self._groups = {k: v for k, v in self._groups.items() if v}
        links = {*self._conduits, *self._weirs, *self._orifices,
                 *(r.tokens[0] for s in ("OUTLETS", "PUMPS") for r in self._inp.rows(s))}
        self.stations = dict(stations)
        for obs, spec in self.stations.items():
            kind, ident = parse_element(spec)
            if ident not in (self._inverts if kind == "node" else links):
                raise ValueError(f"{label}: station {obs} refers to {spec}, which the file does not have")
        self.observables = list(self.stations)
        topology = "\n".join(sorted(self._inverts)) + "\n" + "\n".join(sorted(links))
        self._origin = f"swmm:{name}:{hashlib.sha1(topology.encode()).hexdigest()[:12]}"

    # -- contract facts ---------------------------------------------------------------------------

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.name!r}, {self.start:%Y-%m-%d %H:%M} … {self.end:%Y-%m-%d %H:%M} UTC, "
                f"Δt {self.dt:g} s, {len(self.quantities)} quantities, {len(self.observables)} series" + ")")

    @property
    def start(self) -> pd.Timestamp:
        """Start of the model's period (UTC)."""
        return self._start

    @property
    def end(self) -> pd.Timestamp:
        """End of the model's period (UTC)."""
        return self._end

    @property
    def dt(self) -> float:
        """SWMM's routing step, s (``ROUTING_STEP``)."""
        return self._dt

    @property
    def output_interval(self) -> float:
        """Default interval of the series, s."""
        return self._interval

    @property
    def numerical_noise(self) -> float:
        """SWMM's convergence tolerance of node heads, m (``HEAD_TOLERANCE``).

        The jitter of its levels under a tiny parameter change. SWMM's default is 0.005 ft, 0.0015 m
        (SWMM 5 user's manual, the [OPTIONS] section).
        """
        return self._head_tolerance

    @property
    def calibration(self) -> CalibrationSetup:
        """Parameters, windows and optimiser defaults of the model."""
        return self._calibration

    @property
    def quantities(self) -> dict[str, Quantity]:
        """The settable quantities (module docstring)."""
        low, high = 1.0, 200.0  # the plausible Strickler range of the embedded engine
        out = {"roughness:factor": Quantity("roughness:factor", "-", 0.01, 100.0,
                                            "factor on the Manning n of every conduit"),
               "friction:global": Quantity("friction:global", "m^(1/3)/s", low, high,
                                           "Strickler k_s of every conduit (n = 1/k_s)")}
        for tag in self._groups:
            out[f"roughness:group:{tag}"] = Quantity(f"roughness:group:{tag}", "-", 0.01, 100.0,
                                                     f"factor on the Manning n of the conduits tagged {tag}")
            out[f"friction:branch:{tag}"] = Quantity(f"friction:branch:{tag}", "m^(1/3)/s", low, high,
                                                     f"Strickler k_s of the conduits tagged {tag}")
        for c in self._conduits:
            out[f"conduit:{c}.roughness"] = Quantity(f"conduit:{c}.roughness", "s/m^(1/3)", 0.001, 1.0,
                                                     f"Manning n of conduit {c}")
        for w, (node, _) in self._weirs.items():
            out[f"weir:{w}.crest_level"] = Quantity(f"weir:{w}.crest_level", "m", self._inverts[node], None,
                                                    f"crest elevation of weir {w} (not below node {node})")
        for o in self._orifices:
            out[f"orifice:{o}.setting"] = Quantity(f"orifice:{o}.setting", "-", 0.0, 1.0,
                                                   f"opening of orifice {o} (0 closed, 1 open)")
        return out

    def default_parameters(self) -> dict[str, float]:
        """The file's own values of the quantities."""
        out = {"roughness:factor": 1.0, **{f"roughness:group:{t}": 1.0 for t in self._groups}}
        out.update({f"conduit:{c}.roughness": n for c, n in self._conduits.items()})
        for key, ids in (("friction:global", list(self._conduits)),
                         *((f"friction:branch:{t}", ids) for t, ids in self._groups.items())):
            values = {self._conduits[c] for c in ids}
            if len(values) == 1:  # a k_s only where its conduits share one n
                out[key] = 1.0 / values.pop()
        for w, (node, offset) in self._weirs.items():
            out[f"weir:{w}.crest_level"] = offset if self._elevation_offsets else self._inverts[node] + offset
        out.update({f"orifice:{o}.setting": 1.0 for o in self._orifices})
        return out

    # -- state ----------------------------------------------------------------------------------------

    @property
    def state_format(self) -> str:
        """Format tag of :meth:`save_state`: a zip of SWMM's hotstart file."""
        return "rivercal-swmm-hotstart-1"

    def save_state(self, state: FileState) -> bytes:
        """The state as bytes (zip of the hotstart file, the time and the model's topology)."""
        return state.to_bytes()

    def load_state(self, data: bytes, fmt: str) -> FileState:
        """A state of this model from :meth:`save_state` bytes; ValueError for another format or model."""
        if fmt != self.state_format:
            raise ValueError(f"state format {fmt!r} is not {self.state_format!r}")
        return FileState.from_bytes(data, origin=self._origin)

    # -- running ----------------------------------------------------------------------------------

    def render(self, parameters: Mapping[str, float], run_start: pd.Timestamp, end: pd.Timestamp,
               interval: float, *, hot: bool, scale: Mapping[str, float] | None = None) -> str:
        """The ``.inp`` text of one run: period, reporting, quantities and hotstart files set.

        ``scale``: factors on the inflows of nodes (their ``[INFLOWS]`` scale factors times the factor). The
        ``[TIMESERIES]`` keep the points of the run's period and the one before and after it.
        """
        inp = self._inp.copy()
        trimmed = self._trimmed_series(run_start, end)
        if trimmed is not None:
            inp.replace_section("TIMESERIES", trimmed)
        for node, factor in (scale or {}).items():
            row = self._inflow_rows[node]
            inp.set_value("INFLOWS", node, 5, f"{float(row.tokens[5]) * float(factor):.10g}")
        d0, t0 = swmm_date(run_start)
        d1, t1 = swmm_date(end)
        for key, value in (("START_DATE", d0), ("START_TIME", t0), ("REPORT_START_DATE", d0),
                           ("REPORT_START_TIME", t0), ("END_DATE", d1), ("END_TIME", t1),
                           ("REPORT_STEP", swmm_step(interval))):
            inp.set_option(key, value)
        factor = float(parameters.get("roughness:factor", 1.0))
        group_of = {c: tag for tag, ids in self._groups.items() for c in ids}
        ks_global = parameters.get("friction:global")
        for c, base in self._conduits.items():
            tag = group_of.get(c)
            ks = parameters.get(f"friction:branch:{tag}", ks_global) if tag is not None else ks_global
            n = float(parameters.get(f"conduit:{c}.roughness", 1.0 / ks if ks is not None else base)) * factor
            if tag is not None:
                n *= float(parameters.get(f"roughness:group:{tag}", 1.0))
            if n != base:
                inp.set_value("CONDUITS", c, 4, f"{n:.10g}")
        for w, (node, _) in self._weirs.items():
            key = f"weir:{w}.crest_level"
            if key in parameters:
                level = float(parameters[key])
                height = level if self._elevation_offsets else level - self._inverts[node]
                inp.set_value("WEIRS", w, 4, f"{height:.10g}")
        files = [f'SAVE HOTSTART "{HOTSTART}"']
        if hot:
            files.insert(0, f'USE HOTSTART "start-{HOTSTART}"')
        inp.replace_section("FILES", files)
        nodes = sorted({parse_element(s)[1] for s in self.stations.values() if s.startswith("node:")})
        links = sorted({parse_element(s)[1] for s in self.stations.values() if s.startswith("link:")})
        inp.replace_section("REPORT", ["INPUT NO", "CONTROLS NO", "SUBCATCHMENTS NONE",
                                       f"NODES {' '.join(nodes)}" if nodes else "NODES NONE",
                                       f"LINKS {' '.join(links)}" if links else "LINKS NONE"])
        return inp.text()

    def simulate(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                 state: FileState | None = None, *, output_interval: float | None = None
                 ) -> tuple[SimulationResult, FileState]:
        """Run SWMM from ``start`` to ``end`` (module docstring).

        Parameters
        ----------
        parameters
            Quantities to set (the rest keep the file's values).
        start, end
            Period (UTC; default the model's); ``end - start`` a multiple of the output interval.
        state
            Hot-start state at ``start`` (None: cold start ``spinup`` hours before ``start``).
        output_interval
            Interval of the series, s (default the model's).

        Returns
        -------
        (SimulationResult, FileState)
            Station series at the output times of [start, end] (``balance`` is None: SWMM reports its
            own continuity) and the state at ``end``.

        Raises
        ------
        SwmmRunError
            When SWMM fails or returns non-finite values; the run folder is kept and named.
        ValueError
            For an unknown quantity, a value out of bounds, a period off the output grid or a state at
            another time.
        """
        run = check_run(self, parameters, start, end, state, output_interval)
        return self._simulate(run.parameters, run.start, run.end, state, run.interval)

    def _simulate(self, parameters: Mapping[str, float], start: pd.Timestamp, end: pd.Timestamp,
                  state: FileState | None, interval: float,
                  scale: Mapping[str, float] | None = None) -> tuple[SimulationResult, FileState]:
        """:meth:`simulate` of checked arguments, the inflows of ``scale``'s nodes scaled (:meth:`render`)."""
        spin = pd.Timedelta(hours=self.spinup) if state is None else pd.Timedelta(0)
        if spin.total_seconds() % interval:
            raise ValueError(f"spin-up ({self.spinup:g} h) is not a multiple of the output interval ({interval:g} s)")
        run_start = start - spin
        run_dir = Path(tempfile.mkdtemp(prefix=f"swmm-{self.name}-", dir=self._base_dir()))
        t0 = _time.perf_counter()
        try:
            text = self.render(parameters, run_start, end, interval, hot=state is not None, scale=scale)
            (run_dir / "model.inp").write_text(text, encoding="utf-8")
            if state is not None:
                (run_dir / f"start-{HOTSTART}").write_bytes(state.files[HOTSTART])
            first = self._run(run_dir, parameters)
            series = read_swmm_output(run_dir / "model.out", self.stations, step=interval)
            hotstart = (run_dir / HOTSTART).read_bytes()
        except SwmmRunError:
            raise
        except (ValueError, OSError, KeyError) as exc:
            raise SwmmRunError(str(run_dir), str(exc)) from None
        wall = _time.perf_counter() - t0
        times = pd.date_range(start, end, freq=pd.Timedelta(seconds=interval))
        if state is not None:  # SWMM reports from one step after its start: the first row is the hot state
            series = pd.concat([pd.DataFrame([first], index=pd.DatetimeIndex([start], name="time")), series])
        series = series.reindex(times)
        series.index.name = "time"
        bad = ~np.isfinite(series.to_numpy())
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise SwmmRunError(str(run_dir), f"no finite value of {series.columns[col]} at {series.index[row]} "
                                             "(the output is missing or truncated there)")
        shutil.rmtree(run_dir, ignore_errors=True)
        result = SimulationResult(series=series, wall_time=wall, source="EPA SWMM 5 (swmm-toolkit)")
        return result, FileState(time=end, files={HOTSTART: hotstart}, origin=self._origin)

    # -- inflow series, trimmed to a run ---------------------------------------------------------------

    @functools.cached_property
    def _series_points(self) -> dict[str, tuple[np.ndarray, list[str]]] | None:
        """Per ``[TIMESERIES]`` series its times (ns, UTC clock) and lines.

        None when a row is not ``Name Date Time Value`` (a file, relative times or several pairs per row): the
        section is then written as it is.
        """
        names, stamps, kept = [], [], []
        for line in self._inp.raw_lines("TIMESERIES"):
            body = line.partition(";")[0].split()
            if not body:
                continue
            if len(body) != 4 or "/" not in body[1] or body[2].count(":") not in (1, 2):
                return None
            names.append(body[0])
            stamps.append(f"{body[1]} {body[2]}" + (":00" if body[2].count(":") == 1 else ""))
            kept.append(line)
        try:
            when = pd.to_datetime(pd.Series(stamps, dtype=object), format="%m/%d/%Y %H:%M:%S").to_numpy()
        except (ValueError, TypeError):
            return None
        when = when.astype("datetime64[ns]").astype(np.int64)
        out: dict[str, tuple[list[int], list[str]]] = {}
        for name, t, line in zip(names, when.tolist(), kept, strict=True):
            times, lines = out.setdefault(name, ([], []))
            if times and t < times[-1]:
                return None
            times.append(t)
            lines.append(line)
        return {k: (np.asarray(t, dtype=np.int64), lines) for k, (t, lines) in out.items()}

    def _trimmed_series(self, start: pd.Timestamp, end: pd.Timestamp) -> list[str] | None:
        """The ``[TIMESERIES]`` lines of [start, end] and the point before and after (None: keep the section)."""
        points = self._series_points
        if points is None:
            return None
        t0, t1 = start.tz_localize(None).value, end.tz_localize(None).value
        out = [";Name Date Time Value"]
        for times, lines in points.values():
            a = max(0, int(np.searchsorted(times, t0, side="right")) - 1)
            b = min(len(times), int(np.searchsorted(times, t1, side="left")) + 1)
            out.extend(lines[a:b])
        return out

    # -- optional capabilities (rivercal.models.capabilities) -----------------------------------------

    @functools.cached_property
    def _inflow_rows(self) -> dict[str, Any]:
        """The flow rows of ``[INFLOWS]`` by node (``Node FLOW Series Type Mfactor Sfactor …``)."""
        return {r.tokens[0]: r for r in self._inp.rows("INFLOWS")
                if len(r.tokens) >= 6 and r.tokens[1].upper() == "FLOW"}

    def perturbable_forcing(self) -> tuple[str, ...]:
        """The flow inflows of ``[INFLOWS]``, as ``inflow:<node>``."""
        return tuple(f"inflow:{node}" for node in self._inflow_rows)

    def simulate_perturbed(self, parameters: Mapping[str, float] | None, start: Any, end: Any,
                           state: FileState | None, factors: np.ndarray, interval: float, *,
                           output_interval: float | None = None) -> tuple[SimulationResult, FileState]:
        """A run whose inflows are scaled by ``factors`` (intervals, inflows): one SWMM run per interval.

        Raises
        ------
        ValueError
            As :meth:`simulate`; for factors of another shape, or an interval that is not a whole number of
            output intervals.
        """
        run = check_run(self, parameters, start, end, state, output_interval)
        factors = np.asarray(factors, dtype=float)
        nodes = list(self._inflow_rows)
        step = pd.Timedelta(seconds=float(interval))
        needed = -(-(run.end - run.start) // step)
        if factors.ndim != 2 or factors.shape[1] != len(nodes) or factors.shape[0] < needed:
            raise ValueError(f"factors must have shape (intervals >= {needed}, {len(nodes)}), got {factors.shape}")
        if step % pd.Timedelta(seconds=run.interval):
            raise ValueError(f"the factors' interval ({float(interval):g} s) must be a whole number of output "
                             f"intervals ({run.interval:g} s)")
        parts: list[pd.DataFrame] = []
        t0, wall = run.start, 0.0
        for k in range(needed):
            t1 = min(t0 + step, run.end)
            result, state = self._simulate(run.parameters, t0, t1, state, run.interval,
                                           scale=dict(zip(nodes, factors[k], strict=True)))
            parts.append(result.series if not parts else result.series.iloc[1:])
            wall += result.wall_time
            t0 = t1
        return SimulationResult(series=pd.concat(parts), wall_time=wall, source="EPA SWMM 5 (swmm-toolkit)"), state

    @functools.cached_property
    def _nodes(self) -> tuple[list[str], tuple[bool, ...]]:
        """The nodes in SWMM's order (the file's), and which of them are storage nodes."""
        names, storage = [], []
        for section in self._inp.sections():
            if section in NODE_SECTIONS:
                for r in self._inp.rows(section):
                    names.append(r.tokens[0])
                    storage.append(section == "STORAGE")
        return names, tuple(storage)

    @functools.cached_property
    def _links(self) -> list[tuple[str, str, str, float]]:
        """The links in SWMM's order: (id, from node, to node, length in m; 1 m but for conduits)."""
        out = []
        for section in self._inp.sections():
            if section in LINK_SECTIONS:
                for r in self._inp.rows(section):
                    length = float(r.tokens[3]) if section == "CONDUITS" else 1.0
                    out.append((r.tokens[0], r.tokens[1], r.tokens[2], length))
        return out

    def state_layout(self) -> StateLayout:
        """The heads at the nodes and the flows of the links, in SWMM's order."""
        return self._layout

    @functools.cached_property
    def _layout(self) -> StateLayout:
        nodes, _ = self._nodes
        at = {n: i for i, n in enumerate(nodes)}
        ends = np.array([[at.get(a, -1), at.get(b, -1)] for _, a, b, _ in self._links], dtype=np.int64).reshape(-1, 2)
        links = {ident: k for k, (ident, *_) in enumerate(self._links)}
        places = {}
        for obs, spec in self.stations.items():
            kind, ident = parse_element(spec)
            places[obs] = at[ident] if kind == "node" else int(ends[links[ident], 0])
        return StateLayout(levels=tuple(f"node:{n}" for n in nodes),
                           discharges=tuple(f"link:{ident}" for ident, *_ in self._links), link_ends=ends,
                           link_length=np.array([max(length, 1.0) for *_, length in self._links], dtype=float),
                           floor=np.array([self._inverts[n] for n in nodes], dtype=float), places=places,
                           forcing_places={f"inflow:{n}": at[n] for n in self._inflow_rows})

    def state_arrays(self, state: FileState) -> tuple[np.ndarray, np.ndarray]:
        """Heads at the nodes (invert + depth, m) and flows of the links (m³/s) of the state's hotstart file."""
        hot = read_hotstart(state.files[HOTSTART], self._nodes[1])
        return self._layout.floor + hot.depth_m, hot.flow_m3s

    def with_state_arrays(self, state: FileState, levels: np.ndarray, discharges: np.ndarray) -> FileState:
        """The state with these heads (m; depths never below zero) and link flows (m³/s) in its hotstart file."""
        hot = read_hotstart(state.files[HOTSTART], self._nodes[1])
        data = hot.with_values(np.asarray(levels, dtype=float) - self._layout.floor, discharges).to_bytes()
        return FileState(time=state.time, files={**state.files, HOTSTART: data}, origin=state.origin)

    def variant_inputs(self) -> VariantInputs:
        """No branches or catchments: a SWMM model's variants take forcing factors only, on its inflow series.

        ``forcing``: per ``inflow:<node>`` its ``[TIMESERIES]`` series times the row's ``Mfactor`` and
        ``Sfactor`` (m³/s; a baseline of the row is left out); None when the section cannot be read as
        ``Name Date Time Value`` rows.
        """
        points = self._series_points
        forcing = None
        if points is not None:
            forcing = {}
            for node, row in self._inflow_rows.items():
                times, lines = points[row.tokens[2]]
                values = np.array([float(line.partition(";")[0].split()[3]) for line in lines])
                scale = float(row.tokens[4]) * float(row.tokens[5])
                forcing[f"inflow:{node}"] = pd.Series(values * scale, index=pd.DatetimeIndex(times, tz="UTC"))
        return VariantInputs(branches={}, inherit=(), catchments=(), rain=None, forcing=forcing)

    def variant(self, *, branch_factors: Mapping[str, float] | None = None, grid_factor: float = 1.0,
                rain_factor: pd.Series | None = None, runoff_factors: Mapping[str, Mapping[str, float]] | None = None,
                forcing_factors: Mapping[str, pd.Series] | None = None) -> SwmmModel:
        """A copy whose inflow series are multiplied by ``forcing_factors`` (per ``inflow:<node>``, UTC index).

        Raises
        ------
        ValueError
            For other kinds of variant (branch friction, grid, rain, runoff: a SWMM model has none of them
            to vary) or an inflow the model does not have.
        """
        if branch_factors or grid_factor != 1.0 or rain_factor is not None or runoff_factors:
            raise ValueError(f"SWMM model {self.name!r} makes variants of its inflows only, not of its friction, "
                             "grid, rain or runoff")
        inp = self._inp.copy()
        points = self._series_points
        if forcing_factors and points is None:
            raise ValueError(f"{self.inp_path}: [TIMESERIES] rows are not all 'Name Date Time Value'; the inflows "
                             "cannot be scaled")
        added: list[str] = []
        renamed: dict[str, str] = {}
        taken = set(points or ())
        for key, factor in (forcing_factors or {}).items():
            node = key.removeprefix("inflow:")
            if node not in self._inflow_rows or not key.startswith("inflow:"):
                raise ValueError(f"SWMM model {self.name!r} has no inflow {key!r} (it has "
                                 f"{', '.join(self.perturbable_forcing())})")
            series = self._inflow_rows[node].tokens[2]
            times, rows = points[series]  # type: ignore[index]
            origin = factor.index[0]
            f = np.interp((pd.DatetimeIndex(times, tz="UTC") - origin).total_seconds(),
                          (factor.index - origin).total_seconds(), factor.to_numpy(dtype=float))
            # the inflow's own copy of its series: another inflow may share the original, with factors of its own
            own = f"{series}@{node}"
            while own in taken:
                own += "_"
            taken.add(own)
            renamed[node] = own
            for row, value in zip(rows, f, strict=True):
                _, date, clock, number = row.partition(";")[0].split()
                added.append(f"{own} {date} {clock} {float(number) * value:.10g}")
        if renamed:
            sections = {name: self._inp.raw_lines(name) for name in self._inp.sections()}
            sections["TIMESERIES"] = sections["TIMESERIES"] + added
            inp = InpFile("\n".join(f"[{name}]\n" + "\n".join(lines) for name, lines in sections.items()),
                          source=self._inp.source)
            for row in inp.rows("INFLOWS"):
                if len(row.tokens) >= 6 and row.tokens[1].upper() == "FLOW" and row.tokens[0] in renamed:
                    row.tokens[2] = renamed[row.tokens[0]]
            inp = InpFile(inp.text(), source=self._inp.source)
        return SwmmModel(inp, self.stations, name=self.name, start=self.start, end=self.end,
                         output_interval=self.output_interval, spinup=self.spinup, calibration=self.calibration,
                         runs_dir=self.runs_dir)

    def _base_dir(self) -> str | None:
        if self.runs_dir is None:
            return None
        self.runs_dir.mkdir(parents=True, exist_ok=True)
        return str(self.runs_dir)

    def _run(self, run_dir: Path, parameters: Mapping[str, float]) -> dict[str, float]:
        """Run SWMM on ``run_dir/model.inp``; return the station values right after the start."""
        from swmm.toolkit import shared_enum, solver

        inp, rpt, out = (str(run_dir / f"model.{ext}") for ext in ("inp", "rpt", "out"))
        first: dict[str, float] = {}
        opened = False
        try:
            solver.swmm_open(inp, rpt, out)
            opened = True
            solver.swmm_start(1)
            for key, value in parameters.items():
                if key.startswith("orifice:"):
                    index = solver.project_get_index(shared_enum.ObjectType.LINK, key[len("orifice:"):-len(".setting")])
                    solver.link_set_target_setting(index, float(value))
            for obs, spec in self.stations.items():
                kind, ident = parse_element(spec)
                if kind == "node":
                    index = solver.project_get_index(shared_enum.ObjectType.NODE, ident)
                    first[obs] = solver.node_get_result(index, shared_enum.NodeResult.HEAD)
                else:
                    index = solver.project_get_index(shared_enum.ObjectType.LINK, ident)
                    first[obs] = solver.link_get_result(index, shared_enum.LinkResult.FLOW)
            while solver.swmm_stride(86400 * 30) != 0:
                pass
            solver.swmm_end()
        except Exception as exc:  # the toolkit raises plain Exceptions that carry SWMM's error text
            raise SwmmRunError(str(run_dir), _one_line(exc) + _report_errors(Path(rpt))) from None
        finally:
            if opened:
                try:
                    solver.swmm_close()
                except Exception:  # closing after a failure must not hide the failure
                    log.debug("swmm_close failed after an error in %s", run_dir)
        return first


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _report_errors(rpt: Path) -> str:
    """SWMM's ERROR lines of a report file, as a suffix of a message."""
    try:
        lines = [ln.strip() for ln in rpt.read_text(encoding="latin-1").splitlines() if "ERROR" in ln]
    except OSError:
        return ""
    return ("; report: " + " | ".join(lines[:3])) if lines else ""
