"""Controllers of ``case.toml`` (``[[controllers]]``): what moves the crest of a weir while the model runs.

Four kinds, each driving the crest of one weir (m AD), evaluated by the engine once per time step:

- ``pid`` — a PID controller on a measured level (or discharge): crest = bias + kp e + ki ∫e dt + kd de/dt
  with e = setpoint - measured (so positive gains raise the crest when the level is below its target: the
  usual control of the level upstream of a weir); conditional integration against wind-up.
- ``interval`` — every ``interval`` seconds, a measured value above setpoint + dead_band/2 lowers the crest
  by ``step``, one below setpoint - dead_band/2 raises it (a negative step reverses the action).
- ``time`` — the crest follows a time table.
- ``relation`` — the crest is a piecewise-linear function of a measured level or discharge.

Every kind keeps its crest within ``min`` .. ``max`` (m AD) and, with ``max_speed`` (m/min), moves it by at
most that speed. The setpoint of a ``pid`` or ``interval`` controller is a constant or a time table.

A measured quantity is named ``"<station>.<quantity>"`` (a series of a station) or ``"<structure>.<quantity>"``
(``h_up``, ``h_down`` or ``Q`` at any structure, with or without a station). Cross-references (weirs,
stations) are checked by :func:`check_controllers`, which the case calls.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from rivercal.errors import FieldProblem
from rivercal.network import STRUCTURE_TABLES, Identifier, Level, Network, Real
from rivercal.network._base import MAX_LEVEL, NetworkModel, num, strictly_increasing

__all__ = [
    "CONTROL_QUANTITIES",
    "Controller",
    "IntervalController",
    "PidController",
    "RelationController",
    "RelationTable",
    "TimeController",
    "TimeTable",
    "check_controllers",
]

#: The calibration targets of a controller, ``control:<id>.<quantity>``, by kind (``value:<k>``: the k-th value,
#: from 1, of its time table or relation table).
CONTROL_QUANTITIES = {
    "pid": ("setpoint", "kp", "ki", "kd", "value:<k>"),
    "interval": ("setpoint", "value:<k>"),
    "time": ("value:<k>",),
    "relation": ("value:<k>",),
}
#: Gains, intervals and speeds must lie within ±MAX_GAIN (a guard against a unit slip, e.g. seconds for hours).
MAX_GAIN = 1.0e6


class TimeTable(NetworkModel):
    """Values (m AD) against time: a seasonal crest or setpoint.

    Attributes
    ----------
    times
        Strictly increasing times (UTC when no offset is given).
    values
        Values at those times, m AD.
    interpolation
        ``linear`` between the times, or ``block``: each value holds until the next time. Before the first
        time the first value holds, after the last the last (unless the table repeats).
    repeat
        ``none``, or ``yearly``: the table repeats every year (its times shifted by whole years), so that
        a summer/winter table of one year serves every year.
    """

    times: list[datetime] = Field(min_length=1, description="strictly increasing times, ISO 8601 (UTC when no "
                                  "offset is given)")
    values: list[Level] = Field(min_length=1, description="values at those times, m AD")
    interpolation: Literal["linear", "block"] = Field(default="linear", description="'linear' between the times, "
                                                      "or 'block' (each value holds until the next time)")
    repeat: Literal["none", "yearly"] = Field(default="none", description="'yearly': the table repeats every year")

    @field_validator("times")
    @classmethod
    def _utc(cls, value: list[datetime]) -> list[datetime]:
        return [t.replace(tzinfo=UTC) if t.tzinfo is None else t.astimezone(UTC) for t in value]

    @model_validator(mode="after")
    def _consistent(self) -> TimeTable:
        if len(self.times) != len(self.values):
            raise FieldProblem("values", f"{len(self.values)} values for {len(self.times)} times; give one value "
                               "per time")
        seconds = [t.timestamp() for t in self.times]
        strictly_increasing(seconds, "times", "s")
        if self.repeat == "yearly" and seconds[-1] - seconds[0] >= 365 * 86400.0:
            raise FieldProblem("times", "a yearly table must span less than a year (its times are repeated every "
                               f"year), but it runs from {_iso(self.times[0])} to {_iso(self.times[-1])}")
        return self


class RelationTable(NetworkModel):
    """Crest (m AD) against a measured level (m AD) or discharge (m³/s), piecewise linear, constant beyond the ends.

    Attributes
    ----------
    x
        Strictly increasing measured values (m AD for a level, m³/s for a discharge).
    crest
        Crest levels at those values, m AD.
    """

    x: list[Real] = Field(min_length=2, description="strictly increasing measured values (m AD or m³/s)")
    crest: list[Level] = Field(min_length=2, description="crest levels at those values, m AD")

    @model_validator(mode="after")
    def _consistent(self) -> RelationTable:
        if len(self.x) != len(self.crest):
            raise FieldProblem("crest", f"{len(self.crest)} crest levels for {len(self.x)} values of x; give one "
                               "per value")
        strictly_increasing(list(self.x), "x", "")
        return self


class _Controller(NetworkModel):
    id: Identifier = Field(description="controller id (calibration targets are 'control:<id>.<quantity>')")
    weir: Identifier = Field(description="id of the weir whose crest the controller sets")
    min: Level = Field(description="lowest crest level the controller sets, m AD")
    max: Level = Field(description="highest crest level the controller sets, m AD")
    max_speed: Real | None = Field(default=None, gt=0, le=MAX_GAIN,
                                   description="largest crest speed, m/min (default: no limit)")

    @model_validator(mode="after")
    def _limits(self) -> _Controller:
        if not self.max > self.min:
            raise FieldProblem("max", f"max ({num(self.max)} m AD) must be above min ({num(self.min)} m AD)")
        return self


class _Measuring(_Controller):
    measure: str = Field(pattern=r"^[A-Za-z0-9_.\-]+\.(h|h_up|h_down|Q)$",
                         description="measured series: '<station>.<quantity>' or '<structure>.<quantity>' "
                         "(h_up, h_down, Q at a structure; h, Q at a station on a branch)")


class _Setpoint(_Measuring):
    setpoint: Level | None = Field(default=None, description="target of the measured quantity (m AD; m³/s for a "
                                   "discharge); or setpoint_table")
    setpoint_table: TimeTable | None = Field(default=None, description="the setpoint against time")

    @model_validator(mode="after")
    def _one_setpoint(self) -> _Setpoint:
        if (self.setpoint is None) == (self.setpoint_table is None):
            raise FieldProblem("setpoint", f"controller {self.id!r} needs a setpoint or a setpoint_table "
                               "(exactly one of them)")
        return self


class PidController(_Setpoint):
    """PID control of a measured level by a weir crest.

    Attributes
    ----------
    kp
        Proportional gain, m of crest per m of error (positive: a level below its setpoint raises the crest).
    ki
        Integral gain, 1/s (m of crest per m·s of accumulated error).
    kd
        Derivative gain, s (m of crest per m/s of error change).
    bias
        Crest at zero error and zero integral, m AD (default: the weir's ``crest_level``).
    """

    type: Literal["pid"]
    kp: Real = Field(ge=-MAX_GAIN, le=MAX_GAIN, description="proportional gain, m crest per m error")
    ki: Real = Field(default=0.0, ge=-MAX_GAIN, le=MAX_GAIN, description="integral gain, 1/s")
    kd: Real = Field(default=0.0, ge=-MAX_GAIN, le=MAX_GAIN, description="derivative gain, s")
    bias: Level | None = Field(default=None, description="crest at zero error and integral, m AD (default: the "
                               "weir's crest_level)")


class IntervalController(_Setpoint):
    """Interval control: a step of the crest every ``interval`` seconds while the measured value is outside its band.

    Attributes
    ----------
    dead_band
        Width of the band around the setpoint in which nothing moves, m (m³/s for a discharge).
    step
        Crest change per action, m (positive: a value above the band lowers the crest).
    interval
        Time between two actions, s (a multiple of the time step is exact; otherwise the next step after it).
    """

    type: Literal["interval"]
    dead_band: Real = Field(ge=0, le=MAX_GAIN, description="width of the band without action, m")
    step: Real = Field(description="crest change per action, m (negative reverses the action)")
    interval: Real = Field(gt=0, le=MAX_GAIN, description="time between actions, s")

    @field_validator("step")
    @classmethod
    def _nonzero(cls, value: float) -> float:
        if value == 0 or abs(value) > MAX_LEVEL:
            raise ValueError(f"step {num(value)} m must be non-zero and within ±{num(MAX_LEVEL)} m")
        return value


class TimeController(_Controller):
    """The crest follows a time table (``table``, m AD)."""

    type: Literal["time"]
    table: TimeTable = Field(description="crest level against time, m AD")


class RelationController(_Measuring):
    """The crest is a function of a measured level or discharge (``table``)."""

    type: Literal["relation"]
    table: RelationTable = Field(description="crest level against the measured value")


#: One ``[[controllers]]`` entry (by its ``type``).
Controller = Annotated[PidController | IntervalController | TimeController | RelationController,
                       Field(discriminator="type")]


def check_controllers(controllers: list, network: Network, parameter_targets: list[tuple[str, str]]) -> None:
    """Check that controllers refer to the network and that calibration targets of controllers exist.

    ``parameter_targets`` are (field path, target) of the case's parameters. Raises :class:`FieldProblem`
    with the path of the offending field.
    """
    weirs = {w.id: w for w in network.weirs}
    structures = {s.id for table, _ in STRUCTURE_TABLES for s in getattr(network, table)}
    stations = {st.id: st for st in network.stations}
    owner: dict[str, str] = {}
    ids: dict[str, object] = {}
    for i, c in enumerate(controllers):
        if c.id in ids:
            raise FieldProblem(f"controllers[{i}].id", f"controller id {c.id!r} is used twice")
        ids[c.id] = c
        if c.weir not in weirs:
            raise FieldProblem(f"controllers[{i}].weir", f"controller {c.id!r} refers to unknown weir {c.weir!r}")
        if c.weir in owner:
            raise FieldProblem(f"controllers[{i}].weir", f"weir {c.weir!r} is already driven by controller "
                               f"{owner[c.weir]!r}; one controller per weir")
        owner[c.weir] = c.id
        if weirs[c.weir].crest_series is not None:
            raise FieldProblem(f"controllers[{i}].weir", f"weir {c.weir!r} follows a time series (crest_series); "
                               "a controlled weir has a constant crest_level as its starting crest")
        if hasattr(c, "measure"):
            name, quantity = c.measure.rsplit(".", 1)
            if name in stations:
                listed = stations[name].observables
                if c.measure not in listed:
                    raise FieldProblem(f"controllers[{i}].measure", f"station {name!r} has no series {c.measure!r} "
                                       f"(it has {', '.join(listed)})")
            elif name in structures:
                if quantity not in ("h_up", "h_down", "Q"):
                    raise FieldProblem(f"controllers[{i}].measure", f"at structure {name!r} the quantity must be "
                                       f"h_up, h_down or Q, not {quantity!r}")
            else:
                raise FieldProblem(f"controllers[{i}].measure", f"{c.measure!r}: {name!r} is neither a station nor "
                                   "a structure")
    for path, target in parameter_targets:
        if target.startswith("weir:") and target[5:-12] in owner:
            raise FieldProblem(path, f"weir {target[5:-12]!r} is driven by controller {owner[target[5:-12]]!r}; "
                               "calibrate the controller's quantities (control:<id>.<quantity>) instead")
        if not target.startswith("control:"):
            continue
        ident, _, quantity = target[len("control:"):].rpartition(".")
        if ident not in ids:
            known = ", ".join(repr(k) for k in ids) or "the case has none"
            raise FieldProblem(path, f"{target!r} refers to unknown controller {ident!r} ({known})")
        problem = control_target_problem(ids[ident], quantity)
        if problem:
            raise FieldProblem(path, f"{target!r}: {problem}")


def control_target_problem(controller, quantity: str) -> str:
    """Why ``quantity`` is no calibration target of ``controller`` ('' when it is one)."""
    kind = controller.type
    allowed = CONTROL_QUANTITIES[kind]
    if quantity.startswith("value:"):
        table = table_values(controller)
        if table is None:
            return f"controller {controller.id!r} has no table (values belong to time and relation tables)"
        k = quantity[len("value:"):]
        if not k.isdigit() or not 1 <= int(k) <= len(table):
            return f"value index {k!r} must be 1 .. {len(table)} (the table's values, counted from 1)"
        return ""
    if quantity not in allowed:
        return f"a {kind} controller's quantities are {', '.join(allowed)}"
    if quantity == "setpoint" and getattr(controller, "setpoint", None) is None:
        return (f"controller {controller.id!r} follows a setpoint_table; calibrate its values "
                "(value:<k>) instead")
    return ""


def table_values(controller) -> list[float] | None:
    """The calibratable values of a controller's table (setpoint or crest table, or relation crests), or None."""
    if controller.type == "time":
        return list(controller.table.values)
    if controller.type == "relation":
        return list(controller.table.crest)
    table = getattr(controller, "setpoint_table", None)
    return None if table is None else list(table.values)


def _iso(value: datetime) -> str:
    return value.strftime("%Y-%m-%dT%H:%M:%SZ")
