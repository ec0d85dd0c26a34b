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
"""

from __future__ import annotations

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

from rivercal.models.contract import CalibrationSetup, ExternalRunError, FileState, Quantity, check_run, utc
from rivercal.models.swmm.inp import InpFile, seconds, swmm_date, swmm_step
from rivercal.models.swmm.output import parse_element, read_swmm_output
from rivercal.results import SimulationResult

__all__ = ["SwmmModel", "SwmmRunError"]

log = logging.getLogger(__name__)

HOTSTART = "hotstart.hsf"


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

    def __init__(self, inp: str | Path, stations: Mapping[str, str], *, name: str, start: Any, end: Any,
                 output_interval: float = 3600.0, spinup: float = 0.0,
                 calibration: CalibrationSetup | None = None, runs_dir: str | Path | None = None):
        self.inp_path = Path(inp)
        self._inp = InpFile.read(self.inp_path)
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
               interval: float, *, hot: bool) -> str:
        """The ``.inp`` text of one run: period, reporting, quantities and hotstart files set."""
        inp = self._inp.copy()
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
        parameters, start, end, interval = run.parameters, run.start, run.end, run.interval
        spin = pd.Timedelta(hours=self.spinup) if state is None else pd.Timedelta(0)
        if spin.total_seconds() % interval:
            raise ValueError(f"spin-up ({self.spinup:g} h) is not a multiple of the output interval ({interval:g} s)")
        run_start = start - spin
        run_dir = Path(tempfile.mkdtemp(prefix=f"swmm-{self.name}-", dir=self._base_dir()))
        t0 = _time.perf_counter()
        try:
            text = self.render(parameters, run_start, end, interval, hot=state is not None)
            (run_dir / "model.inp").write_text(text, encoding="utf-8")
            if state is not None:
                (run_dir / f"start-{HOTSTART}").write_bytes(state.files[HOTSTART])
            first = self._run(run_dir, parameters)
            series = read_swmm_output(run_dir / "model.out", self.stations)
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
