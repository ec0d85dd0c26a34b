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

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case.load import Case
from rivercal.engine.geometry import MIN_TOP
from rivercal.network.grid import branch_layout, chainages

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


def _written_without_dump(base):
    """``base`` (a hydrolib-core INI file model) saved without the dump of its whole tree that the INI writer drops.

    hydrolib-core's file model saves itself as ``self._serialize(self.model_dump(), ...)``, but the INI models'
    ``_serialize`` writes from the model's own fields and ignores that dict. The dump reaches into every file
    model below: the MDU's holds all of them, and the external forcing file's holds the whole forcing file once
    per lateral that refers to it. For Dellen (143 laterals) the two discarded dumps were 21 of the export's
    25 s of processor time; the files written are the same.
    """
    from hydrolib.core.dflowfm.ini.models import INIModel

    class Written(base):
        def _save(self, save_settings) -> None:
            if type(self)._serialize is not INIModel._serialize:  # a writer that may use the dump: keep it
                super()._save(save_settings)
                return
            self._serialize({}, save_settings)

    Written.__name__ = Written.__qualname__ = base.__name__
    return Written


@functools.cache
def _fm_model():
    """hydrolib-core's FMModel (the MDU), saved without the dump it drops (:func:`_written_without_dump`)."""
    from hydrolib.core.dflowfm.mdu.models import FMModel

    return _written_without_dump(FMModel)


@functools.cache
def _ext_model():
    """hydrolib-core's ExtModel, saved without the dump it drops (:func:`_written_without_dump`)."""
    from hydrolib.core.dflowfm.ext.models import ExtModel

    return _written_without_dump(ExtModel)


@functools.cache
def _forcing_model():
    """hydrolib-core's ForcingModel, written once however many boundaries, laterals or structures refer to it.

    hydrolib-core saves a file model at every reference to it in the tree it saves (its ``_save`` hook runs
    once per reference): dommel's ``boundaries.bc``, 35,000 rows that 17 boundaries and laterals refer to,
    was written 17 times over, 15 of the export's 23 s. The content is the same each time, so the second
    and later writes to the same file are skipped (and none dumps the tree it drops,
    :func:`_written_without_dump`).
    """
    from hydrolib.core.dflowfm.bc.models import ForcingModel
    from pydantic import PrivateAttr

    class SharedForcingModel(_written_without_dump(ForcingModel)):
        _written_to: Path | None = PrivateAttr(default=None)

        def _save(self, save_settings) -> None:
            target = self._resolved_filepath
            if target is not None and target == self._written_to:
                return
            super()._save(save_settings)
            self._written_to = target

    return SharedForcingModel


_FRICTION = {"strickler": "Strickler", "manning": "Manning", "chezy": "Chezy", "white-colebrook": "WhiteColebrook"}
#: Height of the level without width that closes a closed zw profile in D-Flow FM's eyes, m.
CLOSING_STEP = 0.001
#: D-Flow FM's transition height of every summer dike (``summerDikeTransitionHeight``), m.
DFLOW_SUMMER_DIKE_TRANSITION = 0.5


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


class _Writer:
    """The parts of a D-Flow FM model, one method per file."""

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

    # -- network -------------------------------------------------------------------------------------

    def network(self):
        from hydrolib.core.dflowfm.net.models import Branch, NetworkModel

        net = self.net
        model = NetworkModel()
        model.filepath = Path("network_net.nc")
        nodes = {n.id: n for n in net.nodes}
        xy = {}
        missing = [n for n in net.nodes if n.x is None]
        for k, n in enumerate(net.nodes):
            xy[n.id] = (float(n.x), float(n.y)) if n.x is not None else (1000.0 * k, -1.0e5)
        if missing:
            self.result.notes.append(f"{len(missing)} node(s) without map coordinates were placed on a line")
        structures = {b.id: [s for s in net.structures if s.branch == b.id] for b in net.branches}
        self.points: dict[str, np.ndarray] = {}
        geo_lengths = {}
        for b in net.branches:
            chain = chainages(branch_layout(b, structures[b.id], self.spec.engine.structure_length))
            self.points[b.id] = chain
            a, c = xy[b.from_node], xy[b.to_node]
            if b.geometry:
                geometry = np.asarray(b.geometry, dtype=float)
                geometry[0], geometry[-1] = a, c
            else:
                geometry = np.array([a, c], dtype=float)
            length = float(np.hypot(*np.diff(geometry, axis=0).T).sum())
            if length <= 0:
                geometry = np.array([a, (a[0] + b.length, a[1])], dtype=float)
                length = b.length
            geo_lengths[b.id] = length
            branch = Branch(geometry=geometry, branch_offsets=chain * (length / b.length))
            model.network.mesh1d_add_branch(branch, name=b.id, force_midpoint=False, branch_order=self._order(b))
        m1 = model.network._mesh1d
        by_xy = {(round(x, 6), round(y, 6)): nid for nid, (x, y) in xy.items()}
        m1.network1d_node_id = np.array([by_xy[(round(float(x), 6), round(float(y), 6))]
                                         for x, y in zip(m1.network1d_node_x, m1.network1d_node_y, strict=True)],
                                        dtype=object)
        m1.network1d_node_long_name = m1.network1d_node_id.copy()
        ids = [str(v) for v in m1.network1d_branch_id]
        m1.network1d_branch_length = np.array([self.net.branch(i).length for i in ids], dtype=float)
        offsets = np.asarray(m1.mesh1d_node_branch_offset, dtype=float).copy()
        for k, bi in enumerate(np.asarray(m1.mesh1d_node_branch_id, dtype=int)):
            bid = ids[bi]
            chain = self.points[bid]
            offsets[k] = chain[int(np.argmin(np.abs(chain - offsets[k] * self.net.branch(bid).length
                                                    / geo_lengths[bid])))]
        m1.mesh1d_node_branch_offset = offsets
        del nodes
        return model

    def _order(self, b) -> int:
        """D-Flow FM's ``branchOrder`` of a branch: its order when positive, else -1 (none).

        D-Flow FM interpolates cross-sections across nodes between branches of every order but -1 (flow1d
        ``useBranchOrdersCrs``); the case between branches of a positive order only.
        """
        if b.order is not None and b.order > 0:
            return int(b.order)
        if b.order is not None and b.order != -1:
            self.result.notes.append(f"branch {b.id!r} has order {b.order}, which interpolates no cross-section in a "
                                     "case: written as branchOrder -1 (D-Flow FM would interpolate across nodes "
                                     "between branches of any order but -1)")
        return -1

    # -- cross-sections ----------------------------------------------------------------------------

    def cross_sections(self):
        from hydrolib.core.dflowfm.crosssection.models import CrossDefModel, CrossLocModel, CrossSection

        defs = []
        self.def_ids: dict[tuple[str, str | None], str] = {}
        for p in self.net.profiles:
            defs.append(self._definition(p, p.id, p.friction))
        locs = []
        for b in self.net.branches:
            for k, cs in enumerate(b.cross_sections):
                locs.append(CrossSection(id=f"{b.id}_{k + 1}", branchid=b.id, chainage=cs.chainage, shift=cs.bed_level,
                                         definitionid=cs.profile))
        defs += self.extra_defs
        self._defs = defs
        model_defs = CrossDefModel(definition=defs)
        model_defs.filepath = Path("crsdef.ini")
        model_locs = CrossLocModel(crosssection=locs)
        model_locs.filepath = Path("crsloc.ini")
        self._crossdef_model = model_defs
        return model_defs, model_locs

    def _definition(self, p, did: str, friction: list[str] | None):
        from hydrolib.core.dflowfm.crosssection import models as m

        ids = list(friction) if friction else [self.global_id]
        kind = p.type
        if kind == "rectangular":
            height = p.height if p.height is not None else MIN_TOP
            if not p.closed and (p.height or 0) < MIN_TOP:
                height = MIN_TOP
            return m.RectangleCrsDef(id=did, width=p.width, height=height, closed=bool(p.closed), frictionid=ids[0])
        if kind == "trapezoidal":
            top = max(p.height or 0.0, MIN_TOP)
            widths = [p.bottom_width, p.bottom_width + 2.0 * p.side_slope * top]
            return m.ZWCrsDef(id=did, numlevels=2, levels=[0.0, top], flowwidths=widths, totalwidths=widths,
                              frictionid=ids[0])
        if kind == "circular":
            return m.CircleCrsDef(id=did, diameter=p.diameter, frictionid=ids[0])
        if kind == "zw":
            return self._zw_definition(p, did, ids)
        positions = list(p.friction_positions) if p.friction_positions else [p.y[0], p.y[-1]]
        return m.YZCrsDef(id=did, yzcount=len(p.y), ycoordinates=list(p.y), zcoordinates=list(p.z),
                          conveyance=p.conveyance, sectioncount=len(positions) - 1, frictionpositions=positions,
                          frictionids=ids, singlevaluedz=True)

    def _zw_definition(self, p, did: str, ids: list[str]):
        """A zw profile as a ``zw`` definition, or ``zwRiver`` with its sections and summer dike (``levee*``).

        The levels are the heights above the profile's lowest point (the location's shift is its bed level). A
        closed profile with width left at its top gets a level 1 mm higher without width: D-Flow FM takes a table
        as closed only when no width is left at its top (flow1d ``readTabulatedCS``). A summer dike becomes
        D-Flow FM's levee with its base level at the crest, so that D-Flow FM fills and empties the storage behind
        it along the same curve as the case.
        """
        from hydrolib.core.dflowfm.crosssection import models as m

        total = list(p.storage_widths)
        heights = list(p.heights)
        flow = list(p.flow_widths)
        if p.closed and max(total[-1], flow[-1]) > 0:
            heights.append(heights[-1] + CLOSING_STEP)
            flow.append(0.0)
            total.append(0.0)
            self.result.notes.append(f"profile {p.id!r} is closed with {total[-2]:g} m of width at its top: written "
                                     f"with a level {CLOSING_STEP * 1000:g} mm higher without width, where D-Flow FM "
                                     "closes a table")
        dike = p.summer_dike
        if p.section_widths is None and dike is None:
            return m.ZWCrsDef(id=did, numlevels=len(heights), levels=heights, flowwidths=flow, totalwidths=total,
                              frictionid=ids[0])
        sections = list(p.section_widths) if p.section_widths is not None else [max(flow)]
        sw = sections + [0.0] * (3 - len(sections))
        levee = {}
        if dike is not None:
            base = dike.crest if dike.base is None else dike.base  # flow1d's falling curve ends at it
            levee = {"leveecrestLevel": dike.crest, "leveebaselevel": base, "leveeflowarea": dike.flow_area,
                     "leveetotalrea": dike.total_area}
            if abs(dike.transition - DFLOW_SUMMER_DIKE_TRANSITION) > 1e-12:
                self.result.notes.append(
                    f"the summer dike of profile {p.id!r} fills over {dike.transition:g} m above its crest; D-Flow FM "
                    f"fills every summer dike over {DFLOW_SUMMER_DIKE_TRANSITION:g} m (summerDikeTransitionHeight)")
        return m.ZWRiverCrsDef(id=did, numlevels=len(heights), levels=heights, flowwidths=flow, totalwidths=total,
                               mainwidth=sw[0], fp1width=sw[1], fp2width=sw[2],
                               frictionids=(ids + [ids[-1]] * 3)[:len(sections)], **levee)

    # -- friction ------------------------------------------------------------------------------------

    def frictions(self):
        """Roughness files: the global and the branches' own friction, then one file per friction group.

        Each value a group takes on a branch is a ``[Branch]`` block in its own law: one value, values at
        ``numLocations`` chainages, or (``functionType = waterLevel``) a table of ``numLevels`` levels by
        ``numLocations`` chainages, written level by level as D-Flow FM reads it (flow1d ``scan_roughness_input``).
        """
        from hydrolib.core.dflowfm.friction.models import FrictBranch, FrictGlobal, FrictionModel

        g = self.spec.friction
        branches = [FrictBranch(branchid=b.id, frictiontype=_FRICTION[b.friction.type], functiontype="constant",
                                numlocations=0, frictionvalues=[b.friction.value])
                    for b in self.net.branches if b.friction is not None]
        main = FrictionModel(global_=[FrictGlobal(frictionid=self.global_id, frictiontype=_FRICTION[g.type],
                                                  frictionvalue=g.value)], branch=branches)
        main.filepath = Path(f"roughness-{self.global_id}.ini")
        used = bool(branches) or any(not p.friction for p in self.net.profiles)
        models = [main] if used or self.global_id == "Main" else []  # under another name only when used
        if used and self.global_id != "Main":
            self.result.notes.append(f"the case has a friction group named Main: its global friction and the "
                                     f"branches' own are written as roughness group {self.global_id!r}, which the "
                                     "profiles without friction groups name (D-Flow FM's default group is Main)")
        for group in self.net.friction_groups:
            fm = FrictionModel(
                global_=[FrictGlobal(frictionid=group.id, frictiontype=_FRICTION[group.type],
                                     frictionvalue=group.value)],
                branch=[_branch_block(FrictBranch, bf, group.type) for bf in group.branches])
            fm.filepath = Path(f"roughness-{group.id}.ini")
            models.append(fm)
        return models

    # -- structures ----------------------------------------------------------------------------------

    def _series_forcing(self, key: str, name: str, quantity: str, unit: str):
        """A .bc time-series block of a forcing key (for structure settings, boundaries, laterals)."""
        from hydrolib.core.dflowfm.bc.models import QuantityUnitPair, TimeSeries

        series = self.forcing[key]
        held = _with_spinup(series, self.start, self.case.start)
        minutes = (held.index - self.start).total_seconds().to_numpy() / 60.0
        unit_time = f"minutes since {self.start.strftime('%Y-%m-%d %H:%M:%S')}"
        return TimeSeries(name=name, function="timeseries", timeinterpolation="linear",
                          quantityunitpair=[QuantityUnitPair(quantity="time", unit=unit_time),
                                            QuantityUnitPair(quantity=quantity, unit=unit)],
                          datablock=[[float(t), float(v)] for t, v in zip(minutes, held.to_numpy(), strict=True)])

    def structures(self):
        from hydrolib.core.dflowfm.crosssection.models import CircleCrsDef, RectangleCrsDef
        from hydrolib.core.dflowfm.structure import models as sm

        items = []
        blocks = []
        bc = _forcing_model()(forcing=[])
        bc.filepath = Path("structures.bc")

        def setting(key, name, quantity, unit, constant):
            if key in self.case.forcing:
                blocks.append(self._series_forcing(key, name, quantity, unit))
                return bc
            return constant

        for w in self.net.weirs:
            crest = setting(f"crest:{w.id}", w.id, "weir_crestLevel", "m", w.crest_level)
            items.append(sm.Weir(id=w.id, name=w.id, branchid=w.branch, chainage=w.chainage,
                                 allowedflowdir=w.allowed_flow, crestlevel=crest, crestwidth=w.crest_width,
                                 corrcoeff=w.discharge_coefficient * w.lateral_contraction, usevelocityheight=False))
        for c in self.net.culverts:
            if c.shape == "profile":
                csdef = c.profile
            else:
                csdef = f"culvert_{c.id}"
                if c.shape == "circular":
                    self._defs.append(CircleCrsDef(id=csdef, diameter=c.diameter))
                else:
                    self._defs.append(RectangleCrsDef(id=csdef, width=c.width, height=c.height, closed=True))
            left, right = c.inverts
            items.append(sm.Culvert(id=c.id, name=c.id, branchid=c.branch, chainage=c.chainage,
                                    allowedflowdir=c.allowed_flow, leftlevel=left, rightlevel=right, csdefid=csdef,
                                    length=c.length, inletlosscoeff=c.inlet_loss, outletlosscoeff=c.outlet_loss,
                                    valveonoff=False, bedfrictiontype=_FRICTION[c.friction.type],
                                    bedfriction=c.friction.value, bendlosscoeff=c.bend_loss or None))
        for p in self.net.pumps:
            cap = setting(f"capacity:{p.id}", p.id, "pump_capacity", "m3/s", p.capacity)
            items.append(sm.Pump(id=p.id, name=p.id, branchid=p.branch, chainage=p.chainage, orientation=p.direction,
                                 controlside="suctionSide", numstages=1, capacity=cap,
                                 startlevelsuctionside=[p.start_level], stoplevelsuctionside=[p.stop_level]))
        for o in self.net.orifices:
            gate = setting(f"gate:{o.id}", o.id, "orifice_gateLowerEdgeLevel", "m", o.gate_lower_edge_level)
            items.append(sm.Orifice(id=o.id, name=o.id, branchid=o.branch, chainage=o.chainage,
                                    allowedflowdir=o.allowed_flow, crestlevel=o.crest_level, crestwidth=o.crest_width,
                                    gateloweredgelevel=gate, corrcoeff=o.discharge_coefficient, usevelocityheight=False,
                                    uselimitflowpos=o.max_flow_positive is not None, limitflowpos=o.max_flow_positive,
                                    uselimitflowneg=o.max_flow_negative is not None, limitflowneg=o.max_flow_negative))
        for u in self.net.universal_weirs:
            items.append(sm.UniversalWeir(id=u.id, name=u.id, branchid=u.branch, chainage=u.chainage,
                                          allowedflowdir=u.allowed_flow, numlevels=len(u.y), yvalues=list(u.y),
                                          zvalues=[u.crest_level + z for z in u.z], crestlevel=u.crest_level,
                                          dischargecoeff=u.discharge_coefficient))
        for b in self.net.bridges:
            items.append(sm.Bridge(id=b.id, name=b.id, branchid=b.branch, chainage=b.chainage,
                                   allowedflowdir=b.allowed_flow, csdefid=b.profile, shift=b.bed_level,
                                   inletlosscoeff=b.inlet_loss, outletlosscoeff=b.outlet_loss,
                                   frictiontype=_FRICTION[b.friction.type], friction=b.friction.value,
                                   length=b.length))
        self._crossdef_model.definition = self._defs
        if not items:
            return None
        bc.forcing = blocks
        model = sm.StructureModel(structure=items)
        model.filepath = Path("structures.ini")
        return model

    # -- storage, initial state --------------------------------------------------------------------------

    def storage_nodes(self):
        from hydrolib.core.dflowfm.storagenode.models import StorageNode, StorageNodeModel

        items = []
        beds = {}
        for b in self.net.branches:
            for node, cs in ((b.from_node, b.cross_sections[0]), (b.to_node, b.cross_sections[-1])):
                bed = b.bed_level_at(0.0 if node == b.from_node else b.length)
                beds[node] = min(beds.get(node, math.inf), bed)
                del cs
        for n in self.net.nodes:
            if n.storage_table is not None:
                t = n.storage_table
                items.append(StorageNode(id=n.id, name=n.id, nodeid=n.id, usetable=True, numlevels=len(t.levels),
                                         levels=list(t.levels), storagearea=list(t.areas), interpolate="linear"))
            elif n.storage_area > 0:
                items.append(StorageNode(id=n.id, name=n.id, nodeid=n.id, usetable=False, bedlevel=beds[n.id],
                                         area=n.storage_area, streetlevel=beds[n.id] + 1.0e4,
                                         streetstoragearea=n.storage_area, storagetype="reservoir"))
        if not items:
            return None
        model = StorageNodeModel(storagenode=items)
        model.filepath = Path("nodeFile.ini")
        return model

    def initial(self):
        """The initial field: ``[initial]`` as a global depth or level; branches' ``initial_levels`` as levels.

        Branches with initial levels get ``[Branch]`` blocks of a water-level 1dField file (chainages and levels),
        after the global field, so that D-Flow FM applies them there instead.
        """
        from hydrolib.core.base.models import DiskOnlyFileModel
        from hydrolib.core.dflowfm.inifield.models import IniFieldModel, InitialField
        from hydrolib.core.dflowfm.onedfield.models import OneDFieldBranch, OneDFieldGlobal, OneDFieldModel

        ini = self.spec.initial
        if ini.level is not None and ini.depth > 0:
            self.result.notes.append("the initial state max(bed + depth, level) has no D-Flow FM counterpart: the "
                                     "initial depth is written, the minimum level is not")
        quantity, value = ("waterdepth", ini.depth) if ini.level is None or ini.depth > 0 else ("waterlevel",
                                                                                                ini.level)
        blocks = []
        for b in self.net.branches:
            if b.initial_levels is None:
                continue
            ch, lv = [float(c) for c in b.initial_levels.chainages], [float(v) for v in b.initial_levels.levels]
            where = {"numlocations": len(ch), "chainage": ch} if len(ch) > 1 else {"numlocations": 0}
            blocks.append(OneDFieldBranch(branchid=b.id, values=lv if len(ch) > 1 else lv[:1], **where))
        files = [(quantity, f"initial_{quantity}.ini",
                  OneDFieldModel(global_=OneDFieldGlobal(quantity=quantity, unit="m", value=value),
                                 branch=blocks if quantity == "waterlevel" else []))]
        if blocks and quantity != "waterlevel":
            files.append(("waterlevel", "initial_waterlevel_branches.ini", OneDFieldModel(branch=blocks)))
        fields = []
        for q, name, model in files:
            model.save(self.out / name)
            fields.append(InitialField(quantity=q, datafile=DiskOnlyFileModel(filepath=Path(name)),
                                       datafiletype="1dField"))
        model = IniFieldModel(initial=fields)
        model.filepath = Path("initialFields.ini")
        return model

    # -- boundaries and laterals ------------------------------------------------------------------------

    def _critical_table(self, index: int) -> tuple[list[float], list[float]]:
        """Levels (m AD) and discharges (m³/s) of the engine's critical-flow table of boundary ``index``."""
        from rivercal.engine.compile import compile_network

        arrays = compile_network(self.net, self.case.spec.engine).arrays
        lo, hi = int(arrays.b_rptr[index]), int(arrays.b_rptr[index + 1])
        return arrays.b_rlev[lo:hi].tolist(), arrays.b_rq[lo:hi].tolist()

    def external_forcing(self):
        from hydrolib.core.dflowfm.bc.models import Constant, QHTable, QuantityUnitPair
        from hydrolib.core.dflowfm.ext.models import Boundary, Lateral

        bc = _forcing_model()(forcing=[])
        bc.filepath = Path("boundaries.bc")
        boundaries, laterals = [], []
        for i, b in enumerate(self.net.boundaries):
            if b.type in ("rating", "critical"):
                levels, discharges = (b.rating.levels, b.rating.discharges) if b.type == "rating" \
                    else self._critical_table(i)
                bc.forcing.append(QHTable(
                    name=b.node, function="qhtable",
                    quantityunitpair=[QuantityUnitPair(quantity="qhbnd discharge", unit="m3/s"),
                                      QuantityUnitPair(quantity="qhbnd waterlevel", unit="m")],
                    datablock=[[q, h] for q, h in zip(discharges, levels, strict=True)]))
                quantity = "qhbnd"
                if b.type == "critical":
                    self.result.notes.append(
                        f"boundary {b.id!r} is a free outfall; D-Flow FM has no such boundary: it is written as the "
                        "QH table of the critical flow at its end (the reach above it is not integrated as rivercal "
                        "does, so D-Flow FM's levels there differ)")
            else:
                quantity = "waterlevelbnd" if b.type == "level" else "dischargebnd"
                unit = "m" if b.type == "level" else "m3/s"
                if b.value is not None:
                    bc.forcing.append(Constant(name=b.node, function="constant",
                                               quantityunitpair=[QuantityUnitPair(quantity=quantity, unit=unit)],
                                               datablock=[[b.value]]))
                else:
                    bc.forcing.append(self._series_forcing(f"boundary:{b.id}", b.node, quantity, unit))
            boundaries.append(Boundary(quantity=quantity, nodeid=b.node, forcingfile=bc))
            if b.id != b.node:
                self.result.notes.append(f"boundary {b.id!r} is named after its node {b.node!r} (D-Flow FM names "
                                         "boundaries by node)")
        for lat in self.net.laterals:
            where = {"nodeid": lat.node} if lat.node is not None else {"branchid": lat.branch,
                                                                      "chainage": lat.chainage}
            if lat.value is not None:
                discharge = lat.value
            else:
                bc.forcing.append(self._series_forcing(f"lateral:{lat.id}", lat.id, "lateral_discharge", "m3/s"))
                discharge = bc
            laterals.append(Lateral(id=lat.id, name=lat.id, **where, discharge=discharge))
        model = _ext_model()(boundary=boundaries, lateral=laterals)
        model.filepath = Path("boundaries.ext")
        return model

    # -- stations --------------------------------------------------------------------------------------

    def stations(self):
        from hydrolib.core.dflowfm.obs.models import ObservationPoint, ObservationPointModel
        from hydrolib.core.dflowfm.obscrosssection.models import ObservationCrossSection, ObservationCrossSectionModel

        points, sections, skipped = [], [], []
        for st in self.net.stations:
            if st.structure is not None:
                skipped.append(st.id)
                continue
            quantities = st.quantities or ["h"]
            if "h" in quantities:
                points.append(ObservationPoint(name=st.id, branchid=st.branch, chainage=st.chainage))
            if "Q" in quantities:
                sections.append(ObservationCrossSection(name=st.id, branchid=st.branch, chainage=st.chainage))
        if skipped:
            self.result.notes.append(f"stations at a structure ({', '.join(skipped)}) are not written: D-Flow FM "
                                     "reports every structure's levels and discharge in its history file")
        obs = crs = None
        if points:
            obs = ObservationPointModel(observationpoint=points)
            obs.filepath = Path("obs.ini")
        if sections:
            crs = ObservationCrossSectionModel(observationcrosssection=sections)
            crs.filepath = Path("obscrs.ini")
        return obs, crs


def _branch_block(cls, bf, group_law: str):
    """A ``[Branch]`` block of a roughness file for a group's entry on a branch (:class:`BranchFriction`)."""
    law = _FRICTION[bf.type or group_law]
    chainages = [float(c) for c in bf.chainages] if bf.chainages is not None else None
    where = {"numlocations": len(chainages), "chainage": chainages} if chainages is not None else {"numlocations": 0}
    if bf.function == "waterlevel":
        rows = [[float(v) for v in row] for row in bf.table]
        values = [row[j] for j in range(len(bf.levels)) for row in rows]  # numLocations values per level, in turn
        return cls(branchid=bf.branch, frictiontype=law, functiontype="waterLevel", numlevels=len(bf.levels),
                   levels=[float(v) for v in bf.levels], frictionvalues=values, **where)
    if bf.values is not None:
        return cls(branchid=bf.branch, frictiontype=law, functiontype="constant",
                   frictionvalues=[float(v) for v in bf.values], **where)
    return cls(branchid=bf.branch, frictiontype=law, functiontype="constant", numlocations=0,
               frictionvalues=[float(bf.value)])


def _with_spinup(series: pd.Series, start: pd.Timestamp, case_start: pd.Timestamp) -> pd.Series:
    """The series from ``start``: held at its value at ``case_start`` before it (a spin-up)."""
    if start >= case_start:
        return series
    t = (series.index - case_start).total_seconds().to_numpy()
    first = float(np.interp(0.0, t, series.to_numpy(dtype=float)))
    after = series[series.index >= case_start]
    head = pd.Series([first, first], index=pd.DatetimeIndex([start, case_start]))
    return pd.concat([head.iloc[:1], head.iloc[1:] if after.index[0] > case_start else head.iloc[:0], after])
