"""Schema of ``case.toml``: the network plus the simulated period, engine settings and initial state.

``rivercal case schema`` prints the JSON Schema of :class:`CaseFile`; ``docs/case-format.md``
documents every field with its unit.

Besides the rules of the network (:mod:`rivercal.network`), a case checks the rules that
depend on the engine settings, so that the engine never meets them: every structure needs its own
segment of ``engine.structure_length`` metres (laid out by :func:`rivercal.network.grid.branch_layout`,
the layout of the engine's grid), a lateral must not land on a node whose level is imposed, and a
level station must not sit inside a structure's segment, where its level would be an average of
the levels up- and downstream of the structure.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from rivercal._time import iso_datetime
from rivercal.case.controllers import Controller, check_controllers
from rivercal.errors import StructureOverlap
from rivercal.network import STRUCTURE_TABLES, Culvert, FieldProblem, Identifier, Level, Network, Pump, Real, Weir
from rivercal.network.grid import Segment, branch_layout, chainages
from rivercal.parameters import Parameter

__all__ = [
    "EARLIEST",
    "LATEST",
    "MAX_SPINUP_HOURS",
    "CalibrationSettings",
    "CaseFile",
    "CaseMeta",
    "Catchment",
    "EngineSettings",
    "FrictionFactor",
    "InitialConditions",
    "Meteo",
    "Window",
]

#: The simulated period must lie within these dates (the range of pandas' nanosecond times, rounded in).
EARLIEST = datetime(1700, 1, 1, tzinfo=UTC)
LATEST = datetime(2200, 1, 1, tzinfo=UTC)
#: The model quantities of the embedded engine that case parameters may target.
_ENGINE_TARGET = re.compile(r"^(weir:[A-Za-z0-9_.\-]+\.crest_level|friction:global|friction:branch:[A-Za-z0-9_.\-]+"
                            r"|friction:group:[A-Za-z0-9_.\-]+|friction:scale|friction:factor:[A-Za-z0-9_.\-]+"
                            r"|control:[A-Za-z0-9_.\-]+\.(setpoint|kp|ki|kd|value:[0-9]+))$")
#: Longest spin-up, h (one leap year).
MAX_SPINUP_HOURS = 8784.0


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class CaseMeta(_Model):
    """Identity and simulated period of a case.

    Attributes
    ----------
    name
        Short name of the case.
    description
        Free text.
    start, end
        Simulated period (UTC; a time without offset is read as UTC), between 1700 and 2200.
    crs
        Coordinate reference system of the map coordinates (node ``x``/``y``, branch geometries), e.g.
        ``"EPSG:28992"`` (Amersfoort / RD New); optional. NetCDF outputs then carry it and each station's
        latitude and longitude.
    vertical_datum
        Name of the datum of every level in the case (m above it), e.g. ``"NAP"``; optional (levels are
        then in m above the case's own datum, "m AD").
    """

    name: str = Field(min_length=1, description="short name of the case")
    description: str = Field(default="", description="free text")
    start: datetime = Field(description="start of the simulated period, ISO 8601 (UTC when no offset is given)")
    end: datetime = Field(description="end of the simulated period, ISO 8601 (UTC when no offset is given)")
    crs: str | None = Field(default=None, min_length=1, description="coordinate reference system of the map "
                            "coordinates, e.g. 'EPSG:28992' (RD New); optional")
    vertical_datum: str | None = Field(default=None, min_length=1, max_length=40, description="name of the datum "
                                       "of all levels, e.g. 'NAP' (levels in m above it); optional")

    @field_validator("crs")
    @classmethod
    def _known_crs(cls, value: str | None) -> str | None:
        if value is None:
            return None
        from pyproj import CRS
        from pyproj.exceptions import CRSError

        try:
            crs = CRS.from_user_input(value)
        except CRSError:
            raise ValueError(f"{value!r} is not a coordinate reference system (e.g. 'EPSG:28992')") from None
        if not crs.is_projected:
            raise ValueError(f"{value!r} ({crs.name}) is not a projected system with coordinates in m; the case's x "
                             "and y are metres")
        return value

    @field_validator("start", "end", mode="before")
    @classmethod
    def _iso(cls, value: Any) -> Any:
        return iso_datetime(value)  # ISO 8601 text or a TOML date; never a number, never a guess

    @field_validator("start", "end")
    @classmethod
    def _utc(cls, value: datetime) -> datetime:
        value = value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)
        if not EARLIEST <= value < LATEST:
            raise ValueError(f"{value.isoformat()} lies outside the supported years {EARLIEST.year}-{LATEST.year - 1}")
        return value

    @model_validator(mode="after")
    def _ordered(self) -> CaseMeta:
        if self.end <= self.start:
            raise FieldProblem(
                "end", f"the period ends ({_iso(self.end)}) before or when it starts ({_iso(self.start)})"
            )
        return self


class EngineSettings(_Model):
    """Numerical settings of the embedded engine.

    Attributes
    ----------
    dt
        Time step, s (0.1-3600).
    theta
        Implicitness of the continuity flux, in [0.5, 1] (1: fully implicit).
    output_interval
        Interval of the station series, s (a multiple of ``dt``).
    max_iterations
        Picard iterations per step for structures and non-linear storage (at least 1).
    tolerance
        Level change below which the iterations of a step stop, m.
    min_depth
        Upwind depth below which a channel link carries no flow, m.
    min_storage_area
        Storage area added at every calculation point so that no point has zero storage, m².
    structure_length
        Length of the short channel segment that holds a structure, m; the calculation points at
        its ends give the levels up- and downstream of the structure. Structures on one branch
        must be far enough apart for each to get its own segment.
    max_velocity
        Velocity above which the run is declared diverged, m/s.
    cross_sections
        ``nearest`` (each calculation point takes the shape of the nearest cross-section) or
        ``interpolated`` (each link takes the cross-section interpolated between the two around its
        middle, at the bed level there, and each point stores the water of its half-links, as D-Flow FM
        does) or ``points`` (each calculation point takes the cross-section interpolated at it, for its storage
        and for the flow of the links it feeds, as Mascaret does).
    courant
        Largest flow Courant number u Δt / Δx (u the speed of the flow) of a (sub-)step, or None: a step whose
        flow would cross a channel link in less than 1/courant of it is divided (SOBEK 3's ``CourantNumber``,
        D-Flow FM's ``CFLMax``).
    """

    dt: Real = Field(default=60.0, ge=0.1, le=3600, description="time step, s (0.1-3600)")
    theta: Real = Field(
        default=1.0, ge=0.5, le=1.0, description="implicitness of the continuity flux, - (0.5-1; 1 = fully implicit)"
    )
    output_interval: Real = Field(
        default=3600.0, gt=0, description="interval of the simulated station series, s (a multiple of dt)"
    )
    max_iterations: int = Field(
        default=4, ge=1, le=50,
        description="most Picard iterations per time step for structures and storage (1-50); the first starts "
        "from the extrapolated level, so one usually suffices",
    )
    tolerance: Real = Field(
        default=1e-4, gt=0, description="level change below which the iterations of a step stop, m"
    )
    min_depth: Real = Field(
        default=1e-3, gt=0, le=1.0, description="upwind depth below which a channel carries no flow, m (at most 1)"
    )
    min_storage_area: Real = Field(
        default=1.0, gt=0, description="storage area added at every calculation point, m²"
    )
    structure_length: Real = Field(
        default=10.0,
        ge=0.1,
        description="length of the channel segment that holds each structure, m; structures on a branch need "
        "this much room each",
    )
    max_velocity: Real = Field(
        default=20.0, gt=0, description="flow velocity above which a run is declared diverged, m/s"
    )
    courant: Real | None = Field(
        default=None, gt=0,
        description="largest flow Courant number u dt / dx (u the speed of the flow) of a (sub-)step (optional): a "
        "step whose flow crosses a channel link faster is divided, as SOBEK 3 (CourantNumber) and D-Flow FM (CFLMax) "
        "do; default: no limit",
    )
    cross_sections: Literal["nearest", "interpolated", "points"] = Field(
        default="nearest",
        description="'nearest': each calculation point takes the shape of the nearest cross-section; "
        "'interpolated': each link takes the cross-section interpolated at its middle and each point the "
        "storage of its half-links (as D-Flow FM); 'points': each calculation point takes the cross-section "
        "interpolated at it, for its storage and the flow of the links it feeds (as Mascaret)",
    )

    @model_validator(mode="after")
    def _interval(self) -> EngineSettings:
        ratio = self.output_interval / self.dt
        if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-9:
            raise FieldProblem(
                "output_interval",
                f"output_interval {self.output_interval:g} s is not a whole multiple of the time step dt "
                f"{self.dt:g} s",
            )
        return self


class InitialConditions(_Model):
    """Cold-start state.

    Attributes
    ----------
    depth
        Initial depth above the bed at every calculation point, m (at most 100 m).
    level
        Optional minimum initial level everywhere, m AD (the level is max(bed + depth, level)).
    spinup
        Duration before ``start`` that is simulated with the forcing held at its start value, h,
        so that a cold start reaches a realistic state; the spin-up is not part of the output.
    """

    depth: Real = Field(
        default=0.5, ge=0, le=100.0, description="initial water depth above the bed everywhere, m (0-100)"
    )
    level: Level | None = Field(
        default=None, description="minimum initial water level everywhere, m AD (optional)"
    )
    spinup: Real = Field(
        default=0.0,
        ge=0,
        le=MAX_SPINUP_HOURS,
        description="spin-up before start with the forcing held at its start value, h (0-8784)",
    )


class Meteo(_Model):
    """Meteorological input of the rainfall-runoff model.

    Attributes
    ----------
    file
        Path of the file relative to the case folder.
    format
        ``knmi-daily``: a KNMI daily station file ("etmgeg"); rain RH, RHX, RHXH, DR and Makkink
        evaporation EV24 are disaggregated to hours (:mod:`rivercal.hydrology.disaggregate`).
    latitude, longitude
        Position of the station, degrees N and E (for the daytime shape of evaporation).
    """

    file: str = Field(min_length=1, description="meteo file, relative to the case folder")
    format: Literal["knmi-daily"] = Field(default="knmi-daily", description="'knmi-daily': KNMI daily station file")
    latitude: Real = Field(default=51.45, ge=-90, le=90, description="station latitude, degrees N")
    longitude: Real = Field(default=5.38, ge=-180, le=180, description="station longitude, degrees E")


class Catchment(_Model):
    """A sub-catchment whose rainfall-runoff feeds a lateral or a discharge boundary.

    Attributes
    ----------
    id
        Identifier, referenced by ``catchment = "<id>"`` of a lateral or boundary.
    area
        Area, ha.
    runoff
        Parameters of the rainfall-runoff model that differ for this catchment from ``[runoff]``.
    """

    id: Identifier
    area: Real = Field(gt=0, le=1e7, description="area, ha")
    runoff: dict[str, Real] = Field(
        default_factory=dict, description="rainfall-runoff parameters that differ from [runoff] for this catchment"
    )


class Window(_Model):
    """A named calibration window (thesis Fig. 4-3: "moderate" and "extreme").

    Attributes
    ----------
    name
        Name used on the command line (``--window moderate``).
    start, end
        Period (UTC), inside the case period.
    description
        Free text.
    """

    name: str = Field(pattern=r"^[A-Za-z][A-Za-z0-9_-]*$", description="window name")
    start: datetime = Field(description="start of the window, ISO 8601 (UTC when no offset is given)")
    end: datetime = Field(description="end of the window, ISO 8601 (UTC when no offset is given)")
    description: str = Field(default="", description="free text")

    @field_validator("start", "end", mode="before")
    @classmethod
    def _iso(cls, value: Any) -> Any:
        return iso_datetime(value)  # ISO 8601 text or a TOML date; never a number, never a guess

    @field_validator("start", "end")
    @classmethod
    def _utc(cls, value: datetime) -> datetime:
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class CalibrationSettings(_Model):
    """Defaults of a calibration of this case.

    Attributes
    ----------
    algorithm
        Name of an optimiser of :mod:`rivercal.optimise` (``dud``, ``trf``, ``sce_ua``, ...).
    options
        Options of that algorithm (for DuD the stopping criteria of thesis Table 4-3: ``max_outer``,
        ``max_inner``, ``abs_tol`` (T1), ``rel_tol`` (T2), ``rel_tol_linear`` (T3), ``max_rel_step``; and
        e.g. ``final_jacobian = "secant"``, ``parallel_line_search = true``);
        checked against the algorithm when a calibration is set up.
    """

    algorithm: str = Field(default="dud", description="optimiser name (rivercal.optimise)")
    options: dict[str, float | int | bool | str] = Field(default_factory=dict, description="options of the algorithm")


class FrictionFactor(_Model):
    """A named factor on the friction of a set of branches and friction groups, keeping their ratios.

    The calibration target ``friction:factor:<id>`` (-) scales the conveyance of every channel link on the listed
    branches and of every link that conveys with a listed group's values (its own value and its values on
    particular branches), as ``friction:scale`` does for the whole model: a Manning n is divided by the factor, a
    Strickler k_s or a Chézy C multiplied by it, so that a factor above 1 always means a smoother bed. Culverts and
    bridges keep their own friction. White-Colebrook friction cannot be scaled (a factor on its roughness height
    does not scale its conveyance).

    Attributes
    ----------
    id
        Name of the factor (the target is ``friction:factor:<id>``).
    branches
        Branch ids whose channel friction the factor scales, whatever friction their cross-sections name.
    groups
        Friction group ids (``[[friction_groups]]``) whose coefficients the factor scales on every branch.
    description
        Free text.

    A branch or group may belong to one factor only; a group that a profile names beside other groups needs those
    groups in the same factor (the profile's links convey relative to its first group).
    """

    id: Identifier = Field(description="name of the factor; the calibration target is friction:factor:<id>")
    branches: list[Identifier] = Field(default_factory=list, description="branches whose channel friction the factor "
                                       "scales (-: n / factor, k_s and C times the factor)")
    groups: list[Identifier] = Field(default_factory=list, description="friction groups whose coefficients the factor "
                                     "scales on every branch")
    description: str = Field(default="", description="free text")

    @model_validator(mode="after")
    def _lists_something(self) -> FrictionFactor:
        if not self.branches and not self.groups:
            raise FieldProblem("branches", f"friction factor {self.id!r} lists no branches and no groups")
        return self


class CaseFile(Network):
    """The whole ``case.toml``: ``[case]``, ``[engine]``, ``[initial]`` and the network tables."""

    case: CaseMeta = Field(description="name and simulated period")
    engine: EngineSettings = Field(default=EngineSettings(), description="numerical settings of the engine")
    initial: InitialConditions = Field(default=InitialConditions(), description="cold-start state")
    meteo: Meteo | None = Field(default=None, description="meteorological input of the rainfall-runoff model")
    runoff: dict[str, Real] = Field(
        default_factory=dict,
        description="parameters of the rainfall-runoff model for all catchments (names and units: "
        "rivercal.hydrology.WalrusParameters; checked when the model is built)",
    )
    catchments: list[Catchment] = Field(default_factory=list, description="sub-catchments that feed laterals")
    parameters: list[Parameter] = Field(default_factory=list, description="calibration parameters of this case")
    calibration: CalibrationSettings = Field(default=CalibrationSettings(), description="calibration defaults")
    windows: list[Window] = Field(default_factory=list, description="named calibration windows")
    controllers: list[Controller] = Field(default_factory=list, description="controllers that set weir crests "
                                          "while the model runs (pid, interval, time, relation)")
    friction_factors: list[FrictionFactor] = Field(
        default_factory=list, description="named factors on the friction of sets of branches and friction groups "
        "(calibration targets friction:factor:<id>)")

    @model_validator(mode="after")
    def _friction_factors_refer_to_the_network(self) -> CaseFile:
        branches = {b.id for b in self.branches}
        groups = {g.id: g for g in self.friction_groups}
        ids: set[str] = set()
        owner: dict[tuple[str, str], tuple[str, str]] = {}  # (kind, id) → (factor, field) that lists it
        for i, f in enumerate(self.friction_factors):
            if f.id in ids:
                raise FieldProblem(f"friction_factors[{i}].id", f"friction factor id {f.id!r} is used twice")
            ids.add(f.id)
            for kind, items, known in (("branch", f.branches, branches), ("group", f.groups, groups)):
                table = "branches" if kind == "branch" else "groups"
                for j, item in enumerate(items):
                    where = f"friction_factors[{i}].{table}[{j}]"
                    if item not in known:
                        listed = "" if kind == "branch" else \
                            f" ({', '.join(repr(g) for g in groups) or 'the case has no [[friction_groups]]'})"
                        raise FieldProblem(where, f"friction factor {f.id!r} lists unknown {kind} {item!r}{listed}")
                    if (kind, item) in owner:
                        other, path = owner[(kind, item)]
                        twice = "twice" if other == f.id else f"also by friction factor {other!r} ({path})"
                        raise FieldProblem(where, f"{kind} {item!r} is scaled {twice}; a {kind} belongs to one "
                                           "factor at most (two factors on one coefficient could not be told apart)")
                    owner[(kind, item)] = (f.id, where)
                    if kind == "group" and (groups[item].type == "white-colebrook" or any(
                            e.type == "white-colebrook" for e in groups[item].branches)):
                        raise FieldProblem(where, f"friction factor {f.id!r}: friction group {item!r} uses "
                                           "White-Colebrook friction, whose conveyance a factor on the roughness "
                                           "height does not scale")
            for j, gid in enumerate(f.groups):
                for p in self.profiles:
                    named = list(dict.fromkeys(getattr(p, "friction", None) or []))
                    missing = [g for g in named if g not in f.groups]
                    if gid in named and missing:
                        raise FieldProblem(f"friction_factors[{i}].groups[{j}]",
                                           f"friction factor {f.id!r}: profile {p.id!r} names friction group {gid!r} "
                                           f"beside {', '.join(repr(g) for g in missing)}, and conveys relative to its "
                                           f"first group {named[0]!r}; list all of its groups in this factor")
        return self

    @model_validator(mode="after")
    def _calibration_refers_to_the_network(self) -> CaseFile:
        weirs = {w.id for w in self.weirs}
        scheduled = {w.id for w in self.weirs if w.crest_series is not None}
        branches = {b.id for b in self.branches}
        names: set[str] = set()
        for i, p in enumerate(self.parameters):
            if p.name in names:
                raise FieldProblem(f"parameters[{i}].name", f"parameter name {p.name!r} is used twice")
            names.add(p.name)
            for j, target in enumerate([*p.targets, *(c.target for c in p.cluster)]):
                if not _ENGINE_TARGET.match(target):
                    raise FieldProblem(f"parameters[{i}].targets[{j}]",
                                       f"parameter {p.name!r}: {target!r} is not a quantity of the embedded engine; "
                                       "expected 'weir:<id>.crest_level', 'friction:global', 'friction:branch:<id>', "
                                       "'friction:group:<id>', 'friction:scale', 'friction:factor:<id>' or "
                                       "'control:<id>.<quantity>'")
                if target.startswith("weir:") and target[5:-12] not in weirs:
                    raise FieldProblem(f"parameters[{i}].targets[{j}]",
                                       f"parameter {p.name!r} refers to unknown weir {target[5:-12]!r}")
                if target.startswith("weir:") and target[5:-12] in scheduled:
                    raise FieldProblem(f"parameters[{i}].targets[{j}]",
                                       f"parameter {p.name!r} sets the crest of weir {target[5:-12]!r}, whose crest "
                                       "follows a time series (crest_series); calibrate a weir with a constant crest")
                if target.startswith("friction:group:") and target[15:] not in {g.id for g in self.friction_groups}:
                    raise FieldProblem(f"parameters[{i}].targets[{j}]",
                                       f"parameter {p.name!r} refers to unknown friction group {target[15:]!r}")
                if target.startswith("friction:factor:") and target[16:] not in {f.id for f in self.friction_factors}:
                    raise FieldProblem(f"parameters[{i}].targets[{j}]",
                                       f"parameter {p.name!r} refers to friction factor {target[16:]!r}, which "
                                       "[[friction_factors]] does not declare")
                if target.startswith("friction:branch:") and target[16:] not in branches:
                    raise FieldProblem(f"parameters[{i}].targets[{j}]",
                                       f"parameter {p.name!r} refers to unknown branch {target[16:]!r}")
        window_names: set[str] = set()
        for i, w in enumerate(self.windows):
            if w.name in window_names:
                raise FieldProblem(f"windows[{i}].name", f"window name {w.name!r} is used twice")
            window_names.add(w.name)
            if not (self.case.start <= w.start < w.end <= self.case.end):
                raise FieldProblem(
                    f"windows[{i}]",
                    f"window {w.name!r} ({_iso(w.start)} .. {_iso(w.end)}) must be a non-empty part of the case "
                    f"period {_iso(self.case.start)} .. {_iso(self.case.end)}",
                )
        return self

    @model_validator(mode="after")
    def _controllers_refer_to_the_network(self) -> CaseFile:
        targets = [(f"parameters[{i}].targets[{j}]", t) for i, p in enumerate(self.parameters)
                   for j, t in enumerate([*p.targets, *(c.target for c in p.cluster)])]
        check_controllers(self.controllers, self, targets)
        return self

    @model_validator(mode="after")
    def _catchments_are_used(self) -> CaseFile:
        known = {c.id: i for i, c in enumerate(self.catchments)}
        if len(known) != len(self.catchments):
            seen: set[str] = set()
            for i, c in enumerate(self.catchments):
                if c.id in seen:
                    raise FieldProblem(f"catchments[{i}].id", f"catchment id {c.id!r} is used twice")
                seen.add(c.id)
        used: set[str] = set()
        for table, items in (("laterals", self.laterals), ("boundaries", self.boundaries)):
            for i, item in enumerate(items):
                if item.catchment is None:
                    continue
                if item.catchment not in known:
                    listed = ", ".join(repr(k) for k in known) or "none are defined"
                    raise FieldProblem(f"{table}[{i}].catchment",
                                       f"{item.id!r} refers to unknown catchment {item.catchment!r} ({listed})")
                used.add(item.catchment)
        if self.catchments and self.meteo is None:
            raise FieldProblem("meteo", "catchments need meteorological input: add a [meteo] table with the file")
        for cid, i in known.items():
            if cid not in used:
                raise FieldProblem(f"catchments[{i}].id",
                                   f"catchment {cid!r} feeds no lateral or boundary (use catchment = {cid!r})")
        return self

    @model_validator(mode="after")
    def _period_fits_output(self) -> CaseFile:
        seconds = (self.case.end - self.case.start).total_seconds()
        ratio = seconds / self.engine.output_interval
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise FieldProblem(
                "case.end",
                f"the simulated period ({_duration(seconds)}) is not a whole multiple of engine.output_interval "
                f"({_duration(self.engine.output_interval)})",
            )
        return self

    @model_validator(mode="after")
    def _fits_the_grid(self) -> CaseFile:
        where = {
            s.id: (f"{table}[{i}]", kind)
            for table, kind in STRUCTURE_TABLES
            for i, s in enumerate(getattr(self, table))
        }
        on_branch: dict[str, list[Weir | Culvert | Pump]] = {b.id: [] for b in self.branches}
        for s in self.structures:
            on_branch[s.branch].append(s)
        length = self.engine.structure_length
        layouts: dict[str, list[Segment]] = {}
        for br in self.branches:
            try:
                layouts[br.id] = branch_layout(br, on_branch[br.id], length)
            except StructureOverlap as exc:
                path, kind = where[exc.structure.id]
                prev_path, prev_kind = where[exc.previous.id]
                gap = abs(exc.structure.chainage - exc.previous.chainage)
                need = (f"each structure needs its own segment of engine.structure_length = {length:g} m; move one "
                        "of them or lower engine.structure_length") if br.points is None else (
                        "each structure needs its own stretch between two calculation points; add a point between "
                        "them to the branch's points")
                raise FieldProblem(
                    f"{path}.chainage",
                    f"{kind} {exc.structure.id!r} at chainage {exc.structure.chainage:g} m of branch {br.id!r} is "
                    f"too close to {prev_kind} {exc.previous.id!r} ({prev_path}, at {exc.previous.chainage:g} m, "
                    f"{gap:g} m away): {need}",
                ) from None
        self._check_laterals(layouts)
        self._check_level_stations(layouts, where)
        return self

    def _check_laterals(self, layouts: dict[str, list[Segment]]) -> None:
        level_nodes = {bd.node: bd.id for bd in self.boundaries if bd.type == "level"}
        if not level_nodes:
            return
        branches = {b.id: b for b in self.branches}
        for i, lat in enumerate(self.laterals):
            if lat.branch is None or lat.chainage is None:
                continue
            chain = chainages(layouts[lat.branch])
            k = int(np.argmin(np.abs(chain - lat.chainage)))
            br = branches[lat.branch]
            node = br.from_node if k == 0 else br.to_node if k == chain.size - 1 else None
            if node in level_nodes:
                raise FieldProblem(
                    f"laterals[{i}].chainage",
                    f"lateral {lat.id!r} at chainage {lat.chainage:g} m of branch {br.id!r} lands on node {node!r} "
                    f"(the nearest calculation point), which has level boundary {level_nodes[node]!r}: the level "
                    "there is imposed, so the inflow would be lost; move the lateral further from that node",
                )

    def _check_level_stations(self, layouts: dict[str, list[Segment]], where: dict[str, tuple[str, str]]) -> None:
        for i, st in enumerate(self.stations):
            if st.branch is None or st.chainage is None or "h" not in (st.quantities or ["h"]):
                continue
            for seg in layouts[st.branch]:
                if seg.structure is not None and seg.a + 1e-9 < st.chainage < seg.b - 1e-9:
                    s = seg.structure
                    kind = where[s.id][1]
                    raise FieldProblem(
                        f"stations[{i}].chainage",
                        f"level station {st.id!r} at chainage {st.chainage:g} m of branch {st.branch!r} lies inside "
                        f"the segment of {kind} {s.id!r} ({seg.a:g}-{seg.b:g} m), where the level jumps; use "
                        f"structure = {s.id!r} with quantities h_up/h_down, or move the station to {seg.a:g} m or "
                        f"{seg.b:g} m",
                    )

    def network(self) -> Network:
        """The network part of the case as a plain :class:`~rivercal.network.Network`."""
        fields = set(Network.model_fields)
        return Network.model_validate(self.model_dump(include=fields, by_alias=True))


def _iso(value: datetime) -> str:
    return value.strftime("%Y-%m-%dT%H:%M:%SZ")


def _duration(seconds: float) -> str:
    if seconds % 3600 == 0:
        return f"{seconds / 3600:g} h"
    return f"{seconds:g} s"
