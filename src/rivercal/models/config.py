"""Schema of ``model.toml``: a model that is not a case — an external program, a SWMM model, a BMI model.

``rivercal model schema`` prints the JSON Schema of :class:`ModelFile`; ``docs/model-format.md``
documents every field. A bad file fails when it is loaded with a :class:`ModelFileError` that names the
file, the field and what is wrong (the discipline of ``case.toml``), never later inside a run.

Common tables: ``[model]`` (name, kind, period, time step, output interval, spin-up), ``[[parameters]]``
(the calibration parameters, as in ``case.toml``; targets are the model's quantities), ``[calibration]``
and ``[[windows]]``. One table per kind: ``[blackbox]``, ``[swmm]`` or ``[bmi]``.
"""

from __future__ import annotations

import re
import tomllib
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from rivercal._time import iso_datetime
from rivercal.case.load import _case_error  # the case.toml wording of pydantic's errors, shared
from rivercal.case.schema import CalibrationSettings, Window
from rivercal.errors import CaseError
from rivercal.parameters import TARGET_PATTERN, Parameter

__all__ = ["MODEL_FILE", "BlackBoxSection", "BmiAssimilation", "BmiSection", "ModelFile", "ModelFileError",
           "ModelMeta", "OutputSpec", "QuantitySpec", "SwmmSection", "read_model_file"]

MODEL_FILE = "model.toml"
#: An observable's name: ``<station>.<quantity>`` with quantity h, h_up, h_down or Q.
OBSERVABLE = r"^[A-Za-z0-9_\-]+\.(h|h_up|h_down|Q)$"
#: A quantity name of a black box: a placeholder, so no ':' (it separates the format) and no braces.
_PLACEHOLDER_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]{0,99}$")
#: A quantity name of a BMI model.
_QUANTITY = re.compile(TARGET_PATTERN)


class ModelFileError(CaseError):
    """A ``model.toml`` (or a file it references) is invalid; names the file, the field and the problem."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class ModelMeta(_Model):
    """``[model]``: identity, kind and time axis of the model."""

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.\-]+$", description="short name of the model")
    kind: Literal["blackbox", "swmm", "bmi"] = Field(description="adapter: blackbox, swmm or bmi")
    description: str = Field(default="", description="free text")
    start: datetime = Field(description="start of the model's period, ISO 8601 (UTC when no offset is given)")
    end: datetime = Field(description="end of the model's period, ISO 8601 (UTC when no offset is given)")
    dt: float | None = Field(default=None, gt=0, le=86400,
                             description="time step, s (black box: required; swmm: the .inp's routing step; bmi: "
                                         "the model's)")
    output_interval: float = Field(default=3600.0, gt=0, description="interval of the simulated series, s")
    spinup: float = Field(default=0.0, ge=0, le=8784,
                          description="h run before the start of a cold-started run (swmm, blackbox)")

    @field_validator("start", "end", mode="before")
    @classmethod
    def _iso(cls, value: Any) -> Any:
        return iso_datetime(value)  # ISO 8601 text or a TOML date; never a number, never a guess

    @field_validator("start", "end")
    @classmethod
    def _utc(cls, value: datetime) -> datetime:
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)

    @model_validator(mode="after")
    def _ordered(self) -> ModelMeta:
        if not self.end > self.start:
            raise ValueError(f"the period ends ({self.end.isoformat()}) before or when it starts "
                             f"({self.start.isoformat()})")
        if (self.spinup * 3600.0) % self.output_interval:
            raise ValueError(f"spinup ({self.spinup:g} h) must be a multiple of output_interval "
                             f"({self.output_interval:g} s)")
        return self


#: Longest text of the user's that a message quotes whole (a longer one is cut, with its length).
_SHOWN = 80


def _quoted(text: str) -> str:
    """A value of the model file as a message quotes it: whole when short, else its start and its length."""
    return repr(text) if len(text) <= _SHOWN else f"{text[:_SHOWN]!r}… ({len(text):,} characters)"


class QuantitySpec(_Model):
    """A settable quantity of a black box (a placeholder of its templates)."""

    unit: str = Field(default="", description="unit of the value")
    min: float | None = Field(default=None, description="lowest allowed value")
    max: float | None = Field(default=None, description="highest allowed value")
    default: float | None = Field(default=None, description="value when a run does not set it (None: required)")
    format: str = Field(default=".10g", description="Python format spec of the value in templates, e.g. .3f")
    description: str = Field(default="", description="free text")

    @field_validator("format")
    @classmethod
    def _format(cls, value: str) -> str:
        try:
            format(1.5, value)
        except ValueError as exc:
            why = str(exc).replace(value, "…") if len(value) > _SHOWN else str(exc)
            raise ValueError(f"{_quoted(value)} is not a format spec for a number ({why})") from None
        return value

    @model_validator(mode="after")
    def _bounds(self) -> QuantitySpec:
        if self.min is not None and self.max is not None and not self.max > self.min:
            raise ValueError(f"max {self.max} must be above min {self.min}")
        if self.default is not None:
            if (self.min is not None and self.default < self.min) or (self.max is not None and self.default > self.max):
                raise ValueError(f"default {self.default} lies outside [{self.min}, {self.max}]")
        return self


class TemplateSpec(_Model):
    """An input file rendered per run from a template with ``{{NAME}}`` / ``{{NAME:FORMAT}}`` placeholders."""

    source: str = Field(min_length=1, description="template file, relative to the model folder")
    target: str | None = Field(default=None, description="file written in the run folder (default: source without "
                                                         "a .tmpl / .template suffix)")

    @property
    def target_name(self) -> str:
        """The file the rendered template becomes."""
        if self.target:
            return self.target
        for suffix in (".tmpl", ".template"):
            if self.source.endswith(suffix):
                return self.source[: -len(suffix)]
        raise ValueError(f"template {_quoted(self.source)}: give a target (the source has no .tmpl or .template "
                         "suffix)")


class OutputSpec(_Model):
    """An output file of a black box and how its variables map to ``<station>.<quantity>``."""

    reader: Literal["csv", "netcdf", "pixml", "swmm"] = Field(description="csv, netcdf (CF), pixml or swmm")
    file: str = Field(min_length=1, description="file in the run folder")
    series: dict[str, str] = Field(min_length=1, description="'<station>.<quantity>' → variable: csv: a column; "
                                   "netcdf: a variable, or 'variable@id' of a CF timeSeries; pixml: "
                                   "'locationId/parameterId'; swmm: 'node:<id>' (head) or 'link:<id>' (flow)")
    time_column: str = Field(default="time", description="csv: the column of ISO 8601 times")

    @field_validator("series")
    @classmethod
    def _names(cls, value: dict[str, str]) -> dict[str, str]:
        for name in value:
            if not re.match(OBSERVABLE, name):
                raise ValueError(f"{_quoted(name)} is not '<station>.<quantity>' with quantity h, h_up, h_down or Q")
        return value


class StateSpec(_Model):
    """Restart files: written by the program at the end of a run, given back to it for a hot start."""

    restart_out: list[str] = Field(min_length=1, description="files the program writes at the end of a run")
    restart_in: list[str] = Field(min_length=1, description="where the program reads them at the start of a hot-"
                                                            "started run (same order)")

    @model_validator(mode="after")
    def _pairs(self) -> StateSpec:
        if len(self.restart_in) != len(self.restart_out):
            raise ValueError(f"restart_in has {len(self.restart_in)} files, restart_out {len(self.restart_out)}")
        return self


class BlackBoxSection(_Model):
    """``[blackbox]``: an external program run once per evaluation."""

    folder: str = Field(default=".", description="the model folder (relative to model.toml), copied per run")
    command: list[str] = Field(min_length=1, description="argv of the program (never a shell); {run_dir}, {start}, "
                               "{end}, {run_start}, {python} are substituted")
    env: dict[str, str] = Field(default_factory=dict, description="extra environment variables of the program")
    timeout: float = Field(default=600.0, gt=0, description="seconds a run may take before it is stopped")
    templates: list[TemplateSpec] = Field(default_factory=list, description="input files rendered per run")
    quantities: dict[str, QuantitySpec] = Field(min_length=1, description="settable quantities (placeholders)")
    outputs: list[OutputSpec] = Field(min_length=1, description="output files and their series")
    state: StateSpec | None = Field(default=None, description="restart files for hot starts")
    runs_dir: str | None = Field(default=None, description="where run folders go (default: a temporary folder)")
    keep_failed: int = Field(default=5, ge=0, description="failed run folders kept (the newest)")
    keep: bool = Field(default=False, description="keep the folders of successful runs too")

    @field_validator("quantities")
    @classmethod
    def _quantity_names(cls, value: dict[str, QuantitySpec]) -> dict[str, QuantitySpec]:
        for name in value:
            if not _PLACEHOLDER_NAME.match(name):
                raise ValueError(f"quantity name {_quoted(name)}: use letters, digits and _ . - (starting with a "
                                 "letter; it is a placeholder {{name}} or {{name:format}} of the templates)")
            if name in _BUILTIN:
                raise ValueError(f"quantity name {_quoted(name)} is a built-in placeholder ({', '.join(_BUILTIN)})")
        return value


#: Placeholders of black-box templates that rivercal fills itself (times take a strftime format).
_BUILTIN = ("start", "end", "run_start", "run_dir", "hot", "dt", "output_interval")


class SwmmSection(_Model):
    """``[swmm]``: an EPA SWMM 5 input file and the objects its stations are."""

    inp: str = Field(min_length=1, description="the .inp file, relative to model.toml")
    stations: dict[str, str] = Field(min_length=1, description="'<station>.<quantity>' → 'node:<id>' (head, m) or "
                                                               "'link:<id>' (flow, m³/s)")

    @field_validator("stations")
    @classmethod
    def _names(cls, value: dict[str, str]) -> dict[str, str]:
        for name, spec in value.items():
            if not re.match(OBSERVABLE, name):
                raise ValueError(f"{name!r} is not '<station>.<quantity>' with quantity h, h_up, h_down or Q")
            kind = spec.partition(":")[0]
            if kind not in ("node", "link") or not spec.partition(":")[2]:
                raise ValueError(f"{name}: {spec!r} is not 'node:<id>' or 'link:<id>'")
            if (kind == "node") != (name.rpartition(".")[2] != "Q"):
                raise ValueError(f"{name}: a level is a node's head, a discharge a link's flow (got {spec!r})")
        return value


class BmiVariable(_Model):
    """A BMI variable at one element of its grid (or all of them)."""

    var: str = Field(min_length=1, description="BMI variable name")
    index: int | None = Field(default=None, ge=0, description="element of the variable's grid (None: every element)")
    unit: str = Field(default="", description="unit (default: the model's get_var_units)")
    min: float | None = Field(default=None, description="lowest allowed value")
    max: float | None = Field(default=None, description="highest allowed value")


class BmiAssimilation(_Model):
    """``[bmi.assimilate]``: the variables that state updating reads and writes (:mod:`rivercal.online.assimilation`).

    ``levels`` holds the water levels at the nodes of an unstructured grid and ``discharges`` the discharges on
    its edges; both must be state variables (``[bmi] state``). ``derived`` names state variables the component
    computes from them when they are set (e.g. volumes, velocities): a state written back leaves them out.
    ``forcing`` names, per inflow or lateral, a variable (and element) that scales it (a factor, 1: as it is).
    """

    levels: str = Field(min_length=1, description="BMI variable of the levels at the grid's nodes, m")
    discharges: str = Field(min_length=1, description="BMI variable of the discharges on the grid's edges, m3/s")
    floor: str | None = Field(default=None, description="BMI variable of the lowest level at each node (the bed), m")
    derived: list[str] = Field(default_factory=list, description="state variables the component derives from the "
                                                                 "levels and discharges")
    forcing: dict[str, BmiVariable] = Field(default_factory=dict, description="inflow or lateral → the variable (and "
                                                                              "element) of its scale factor")


class BmiSection(_Model):
    """``[bmi]``: a Python class that implements the Basic Model Interface."""

    component: str = Field(pattern=r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$", description="'package.module:Class'")
    config: str | None = Field(default=None, description="configuration file passed to initialize, relative to "
                                                         "model.toml")
    quantities: dict[str, BmiVariable] = Field(default_factory=dict, description="settable quantities")
    stations: dict[str, BmiVariable] = Field(min_length=1, description="'<station>.<quantity>' → variable and index")
    state: list[str] = Field(default_factory=list, description="BMI variables that make up the state (hot starts)")
    assimilate: BmiAssimilation | None = Field(default=None, description="the variables of state updating")

    @model_validator(mode="after")
    def _checks(self) -> BmiSection:
        if self.assimilate is not None:
            lacking = [v for v in (self.assimilate.levels, self.assimilate.discharges, *self.assimilate.derived)
                       if v not in self.state]
            if lacking:
                raise ValueError(f"assimilate: {lacking[0]!r} is not one of the state variables ([bmi] state)")
        for name in self.quantities:
            if not _QUANTITY.match(name):
                raise ValueError(f"quantity name {name!r}: use letters, digits and _ . : - / (starting with a letter)")
        for name, v in self.stations.items():
            if not re.match(OBSERVABLE, name):
                raise ValueError(f"{name!r} is not '<station>.<quantity>' with quantity h, h_up, h_down or Q")
            if v.index is None:
                raise ValueError(f"station {name}: give the index of the grid element")
        return self


class ModelFile(_Model):
    """The whole ``model.toml``."""

    model: ModelMeta = Field(description="name, kind and time axis")
    blackbox: BlackBoxSection | None = Field(default=None, description="kind = 'blackbox'")
    swmm: SwmmSection | None = Field(default=None, description="kind = 'swmm'")
    bmi: BmiSection | None = Field(default=None, description="kind = 'bmi'")
    parameters: list[Parameter] = Field(default_factory=list, description="calibration parameters of this model")
    calibration: CalibrationSettings = Field(default=CalibrationSettings(), description="calibration defaults")
    windows: list[Window] = Field(default_factory=list, description="named calibration windows")

    @model_validator(mode="after")
    def _one_kind(self) -> ModelFile:
        given = [k for k in ("blackbox", "swmm", "bmi") if getattr(self, k) is not None]
        if given != [self.model.kind]:
            raise ValueError(f"model.kind is {self.model.kind!r}: give the table [{self.model.kind}] "
                             f"and no other of [blackbox], [swmm], [bmi] (found: {', '.join(given) or 'none'})")
        if self.model.kind == "blackbox" and self.model.dt is None:
            raise ValueError("model.dt: a black box needs its time step, s")
        names: set[str] = set()
        for p in self.parameters:
            if p.name in names:
                raise ValueError(f"parameter name {p.name!r} is used twice")
            names.add(p.name)
        for w in self.windows:
            if not (self.model.start <= w.start < w.end <= self.model.end):
                raise ValueError(f"window {w.name!r} must be a non-empty part of the model's period")
        return self


def read_model_file(path: str | Path) -> ModelFile:
    """Read and validate a ``model.toml`` (its own content only; the adapters check referenced files).

    Raises
    ------
    ModelFileError
        Naming the file, the field and the problem.
    """
    path = Path(path)
    label = str(path)
    try:
        data: dict[str, Any] = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ModelFileError(f"not valid TOML: {exc}", file=label) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"cannot be read: {exc}", file=label) from None
    try:
        return ModelFile.model_validate(data)
    except ValidationError as exc:
        err = _case_error(exc, label)
        raise ModelFileError(err.reason, file=label, field=err.field) from None
