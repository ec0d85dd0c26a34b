"""``export_dhydro``: a case → D-Flow FM 1D files, written with hydrolib-core.

Case → D-Flow FM:

- nodes and branches → the UGRID 1D network (``network_net.nc``), with the case's calculation points
  (its own grid: structure segments included) as the 1D mesh, so that a structure lies between the two
  points around it as in the case;
- profiles → ``crsdef.ini`` (rectangular → rectangle, trapezoidal → a two-level zw table to the top of
  the engine's table, circular → circle, zw → zw or zwRiver, yz → yz); cross-sections → ``crsloc.ini``
  with shift = bed level;
- friction: the global friction and the branches' own → friction group ``Main`` (``roughness-Main.ini``,
  one ``[Branch]`` block per branch with its own friction); friction groups → one roughness file each;
- structures → ``structures.ini`` (settings that follow a series → ``structures.bc``); culverts of an
  analytic shape get a circle or closed rectangle definition of their own;
- node storage → ``nodeFile.ini``; boundaries and laterals → ``boundaries.ext`` + ``boundaries.bc``
  (laterals fed by a catchment carry the catchment's runoff as a time series); stations on a branch →
  observation points (``h``) and observation cross-sections (``Q``). Stations at a structure are not
  written: D-Flow FM reports every structure's levels and discharge in its history file, and the import
  makes a station of every structure;
- ``[initial]`` → ``initialFields.ini``; the period, time step and output interval → the MDU. A spin-up
  becomes an earlier start with the forcing held at its start value, which is what a spin-up is.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from rivercal.case.load import Case
from rivercal.io.dhydro._export_forcing import _ForcingFiles
from rivercal.io.dhydro._export_models import _fm_model
from rivercal.io.dhydro._export_network import _NetworkFiles

__all__ = ["SETTINGS_FILE", "ExportResult", "export_dhydro", "read_engine_settings"]

#: The file beside an exported MDU with the engine settings D-Flow FM files cannot express.
SETTINGS_FILE = "rivercal.ini"
#: Engine settings written there: case field → key.
_ENGINE_KEYS = {"cross_sections": "crossSections", "theta": "theta", "min_depth": "minDepth",
                "min_storage_area": "minStorageArea", "max_iterations": "maxIterations", "tolerance": "tolerance",
                "max_velocity": "maxVelocity", "structure_length": "structureLength", "dt": "timeStep",
                "courant": "courant"}


def _write_engine_settings(engine, path: Path) -> None:
    lines = ["# Engine settings of the rivercal case this model was exported from (D-HYDRO does not read this",
             "# file; rivercal's import does).", "[engine]"]
    lines += [f"{key} = {getattr(engine, name)}" for name, key in _ENGINE_KEYS.items()
              if getattr(engine, name) is not None]  # an optional setting not given stays unwritten
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def read_engine_settings(folder: Path) -> tuple[dict | None, list[tuple[int, str]], list[str]]:
    """The engine settings an export left beside its MDU (case fields → values), and what is wrong with them.

    Returns
    -------
    settings, errors, warnings
        The settings (None without the file); per unusable line (line number, what is wrong); warnings
        (unknown keys). Each value is checked with the case's own rules for the engine settings.
    """
    from pydantic import ValidationError

    from rivercal.case.schema import EngineSettings
    from rivercal.io.dhydro._source import IniIndex

    path = Path(folder) / SETTINGS_FILE
    if not path.is_file():
        return None, [], []
    try:
        index = IniIndex.read(path)
    except OSError as exc:
        return None, [(0, f"cannot be read ({exc.strerror or exc})")], []
    errors: list[tuple[int, str]] = [(line, f"{text[:60]!r} is not 'key = value'") for line, text in index.stray]
    warnings: list[str] = []
    out: dict = {}
    lines: dict[str, int] = {}
    engine = index.of("engine")
    if not engine:
        errors.append((1, "no [engine] section (the file rivercal's export writes has one)"))
    for section in index.sections:
        if section.header.lower() != "engine":
            warnings.append(f"{SETTINGS_FILE}, line {section.line}: section [{section.header}] is not read")
    keys = {key.lower(): name for name, key in _ENGINE_KEYS.items()}
    for section in engine:
        for key, found in section.keys.items():
            raw = found[0]
            name = keys.get(key)
            if name is None:
                warnings.append(f"{SETTINGS_FILE}, line {raw.line}: unknown key {raw.key} read past")
                continue
            if len(found) > 1:
                warnings.append(f"{SETTINGS_FILE}, lines {', '.join(str(r.line) for r in found)}: {raw.key} given "
                                "more than once; the first is read")
            text = (raw.value or "").strip()
            try:
                value = text if name == "cross_sections" else int(text) if name == "max_iterations" else float(text)
                EngineSettings.model_validate({name: value, **({"dt": 1e-1, "output_interval": 1e-1}
                                                               if name not in ("dt", "output_interval") else {})})
            except (ValueError, ValidationError) as exc:
                problem = (exc.errors(include_url=False)[0]["msg"] if isinstance(exc, ValidationError)
                           else "not a number")
                errors.append((raw.line, f"{raw.key} = {text}: {problem}"))
                continue
            out[name] = value
            lines[name] = raw.line
    return out, errors, warnings



@dataclass
class ExportResult:
    """What an export wrote.

    Attributes
    ----------
    mdu
        The MDU file.
    files
        Every file written.
    notes
        What the D-Flow FM files express differently from the case.
    """

    mdu: Path
    files: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def export_dhydro(case: Case, out: Path | str, *, forcing: dict[str, pd.Series] | None = None) -> ExportResult:
    """Write a case as a D-Flow FM 1D model.

    Parameters
    ----------
    case
        The case.
    out
        Folder to write (created).
    forcing
        The forcing series by key (``boundary:<id>``, ``lateral:<id>``) including the runoff of
        catchment-fed ones; default ``case.forcing`` plus the catchments' runoff
        (:func:`rivercal.hydrology.catchments.catchment_forcing`).

    Returns
    -------
    ExportResult
        The MDU, the files and the notes.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if forcing is None:
        forcing = dict(case.forcing)
        if case.spec.catchments:
            from rivercal.hydrology.catchments import catchment_forcing

            forcing.update(catchment_forcing(case))
    spec = case.spec
    result = ExportResult(mdu=out / f"{case.name}.mdu")
    spin = pd.Timedelta(hours=float(spec.initial.spinup))
    start = case.start - spin
    if spin > pd.Timedelta(0):
        result.notes.append(f"the spin-up of {spec.initial.spinup:g} h becomes an earlier start, {start.isoformat()}, "
                            "with the forcing held at its value at the case start")
    fm = _fm_model()()
    fm.filepath = result.mdu
    w = _Writer(case, out, start, forcing, result)
    fm.geometry.netfile = w.network()
    defs, locs = w.cross_sections()
    fm.geometry.crossdeffile = defs
    fm.geometry.crosslocfile = locs
    fm.geometry.frictfile = w.frictions()
    structures = w.structures()
    if structures is not None:
        fm.geometry.structurefile = [structures]
    storage = w.storage_nodes()
    if storage is not None:
        fm.geometry.storagenodefile = storage
    fm.geometry.inifieldfile = w.initial()
    fm.external_forcing.extforcefilenew = w.external_forcing()
    obs, crs = w.stations()
    if obs is not None:
        fm.output.obsfile = [obs]
    if crs is not None:
        fm.output.crsfile = [crs]
    t = fm.time
    t.refdate = int(start.strftime("%Y%m%d"))
    offset = (start - start.normalize()).total_seconds()
    t.tunit = "S"
    t.tstart = offset
    t.tstop = offset + (case.end - start).total_seconds()
    t.dtuser = float(spec.engine.output_interval)
    t.dtmax = float(spec.engine.dt)
    t.dtinit = float(spec.engine.dt)
    fm.output.hisinterval = [float(spec.engine.output_interval), 0.0, 0.0]
    fm.numerics.teta0 = float(spec.engine.theta)
    fm.geometry.dxdoubleat1dendnodes = False
    fm.physics.uniffricttype = {"chezy": 0, "manning": 1, "white-colebrook": 2}.get(spec.friction.type, 1)
    if spec.friction.type == "strickler":
        fm.physics.uniffricttype = 1
        fm.physics.uniffrictcoef1d = 1.0 / spec.friction.value
        result.notes.append("the MDU's uniform friction is the global Strickler value as a Manning n (1/k_s); the "
                            "friction that counts is in roughness-Main.ini")
    else:
        fm.physics.uniffrictcoef1d = float(spec.friction.value)
    fm.save(recurse=True)
    _write_engine_settings(spec.engine, out / SETTINGS_FILE)
    result.notes.append(f"the engine settings that D-Flow FM files cannot express are in {SETTINGS_FILE} (D-HYDRO "
                        "ignores it; rivercal's import reads it)")
    if spec.controllers:
        result.notes.append(f"the {len(spec.controllers)} controllers ([[controllers]]) are not exported (no D-HYDRO "
                            "RTC files are written): their weirs keep their crest_level")
    result.files = sorted(p for p in out.iterdir() if p.is_file())
    (out / "export.md").write_text(_report(case, result), encoding="utf-8")
    result.files.append(out / "export.md")
    return result


def _report(case: Case, result: ExportResult) -> str:
    lines = ["# Export of a case to D-Flow FM", "", f"- case: `{case.root}`", f"- model: `{result.mdu}`", "",
             "## Differences", ""]
    lines += [f"- {n}" for n in result.notes] or ["None."]
    lines += ["", "## Files", ""] + [f"- `{p.name}`" for p in result.files]
    return "\n".join(lines) + "\n"


class _Writer(_NetworkFiles, _ForcingFiles):
    """The parts of a D-Flow FM model, one method per file.

    The methods are in :mod:`rivercal.io.dhydro._export_network` (network, cross-sections, friction) and
    :mod:`rivercal.io.dhydro._export_forcing` (structures, storage, initial state, forcing, stations).
    """

    def __init__(self, case: Case, out: Path, start: pd.Timestamp, forcing: dict[str, pd.Series],
                 result: ExportResult):
        self.case = case
        self.spec = case.spec
        self.net = case.network
        self.out = out
        self.start = start
        self.forcing = forcing
        self.result = result
        self.extra_defs: list = []
        # the friction id of the global and the branches' own friction: D-Flow FM's default group Main, unless the
        # case has a friction group of that name
        groups = {g.id for g in self.net.friction_groups}
        self.global_id = "Main"
        while self.global_id in groups:
            self.global_id += "_global"
