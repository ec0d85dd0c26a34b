"""The configuration of the on-line service (:class:`OnlineConfig`), stored with its run.

The configuration is checked in one place, whoever makes it — the command line, the Delft-FEWS module or a
script: :meth:`OnlineConfig.from_options` reads it from text (``"FA,Wd"``, ``"7D"``, ``"FA=5,Wd=0.1"``) or
values, the dataclass checks every value when it is made, and :meth:`OnlineConfig.check_model` checks it
against a model (its parameters, their quantities, a dependency map). Every problem is an
:class:`OnlineConfigError` that names the field, the value and what is wrong; a caller names the field its own
way (``--window``, ``property 'window'``) with :meth:`OnlineConfigError.describe`.

:func:`check_schedule` checks the times of a run against its model before anything runs: the window,
the cycle, the horizon and the warm-up are whole numbers of the service's time step (the output interval of
its forecasts, ``OnlineConfig.output_interval_s``), cycles are issued on it, and every window and forecast
lies inside the model's period.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Literal

import pandas as pd

from rivercal._time import utc
from rivercal.evaluate import DaskCluster, Workers, check_workers
from rivercal.models.capabilities import FromCase
from rivercal.models.contract import Model
from rivercal.observations import DEFAULT_SIGMA
from rivercal.problem import LOSSES
from rivercal.store import Schedule

__all__ = ["DEFAULT_RESOLUTION", "SETTING_NAMES", "WHITE_COLEBROOK_RELATIVE_RESOLUTION", "OnlineConfig",
           "OnlineConfigError", "check_schedule", "default_resolution", "span"]


class OnlineConfigError(ValueError):
    """A field of the on-line configuration is invalid.

    Attributes
    ----------
    field
        The :class:`OnlineConfig` field (``window``, ``max_change`` …).
    value
        The value as given (None when the problem is not one value's, e.g. two fields that contradict).
    problem
        What is wrong, in words.
    """

    def __init__(self, field: str, problem: str, value: Any = None):
        self.field = field
        self.value = value
        self.problem = problem
        super().__init__(self.describe(f"online {field}"))

    def describe(self, label: str) -> str:
        """The message with the field named ``label`` (``--window``, ``property 'window'``)."""
        shown = f"{self.value!r}" if isinstance(self.value, str) else f"{self.value}"
        return f"{label} {shown}: {self.problem}" if self.value is not None else f"{label}: {self.problem}"

    def __reduce__(self):  # keep the fields when the error crosses a process boundary
        return (type(self), (self.field, self.problem, self.value))


#: Resolution d of the identifiability gate and alert floor, by unit (the smallest change that matters in
#: operation): 1 cm of a level or crest, 1 % of a factor, and per friction law the change of the friction that
#: changes the conveyance (∝ k_s ∝ 1/n ∝ C) by about 1.5 %, the share of the operator's 0.5 m^(1/3)/s of
#: Strickler (thesis §4-2) at a typical k_s of 30–35 m^(1/3)/s: Manning n 0.0005 s/m^(1/3) (dn = n dk_s/k_s,
#: 1.5 % of n = 0.033), Chézy 0.5 m^(1/2)/s (C = k_s R^(1/6): the same share of a C of 30–40 m^(1/2)/s at a
#: hydraulic radius of 1–4 m). White-Colebrook's k_n shares the unit m with a crest and is relative: see
#: :data:`WHITE_COLEBROOK_RELATIVE_RESOLUTION`.
DEFAULT_RESOLUTION = {"m^(1/3)/s": 0.5, "s/m^(1/3)": 0.0005, "m^(1/2)/s": 0.5, "m AD": 0.01, "m": 0.01, "-": 0.01}
#: Resolution of a White-Colebrook roughness height k_n, as a share of its value: C = 18 log10(12 R/k_n) moves
#: by 18/ln 10 · Δk_n/k_n = 0.63 m^(1/2)/s for 8 %, about 1.5 % of a C of 40 m^(1/2)/s, as for the other laws.
WHITE_COLEBROOK_RELATIVE_RESOLUTION = 0.08


def default_resolution(parameter: Any) -> float:
    """A parameter's resolution when the configuration names none, in its unit.

    From :data:`DEFAULT_RESOLUTION` by unit; a friction parameter in m (a White-Colebrook k_n, whose targets
    are all ``friction:…``) gets :data:`WHITE_COLEBROOK_RELATIVE_RESOLUTION` of its initial value instead of a
    crest's 1 cm; any other unit 1 % of the parameter's range.
    """
    targets = [str(t) for t in (getattr(parameter, "targets", None) or [])]
    friction = bool(targets) and all(t.startswith("friction:") for t in targets)
    if friction and parameter.unit == "m":
        return WHITE_COLEBROOK_RELATIVE_RESOLUTION * abs(float(parameter.initial))
    return float(DEFAULT_RESOLUTION.get(parameter.unit, 0.01 * (parameter.max - parameter.min)))


@dataclass(frozen=True)
class OnlineConfig:
    """How the service runs; stored with the run, so a restart with another configuration is refused.

    Attributes
    ----------
    parameters
        Names of the model's parameters to estimate (default global friction and the crest shift).
    window, period, horizon
        Calibration window length, time between cycles and forecast horizon (thesis §6-2: 7 d, 1 d;
        48 h).
    warmup
        Simulated time before each window that lets the state adjust to a candidate (its residuals do
        not count).
    algorithm, options
        Optimiser and its options (default: the model's, e.g. the case's ``[calibration]``).
    deadline_s
        Wall-clock limit of one calibration, s; on expiry the cycle is ``aborted`` and the last
        accepted estimate is kept.
    max_change
        Per parameter, the largest change per cycle (the optimiser's box around the warm start), in
        the parameter's unit; missing: its whole range.
    resolution
        Per parameter, the smallest change that matters (identifiability gate scale and alert floor);
        missing: :func:`default_resolution` (by unit and friction law, else 1 % of the range).
    gate_sv, gate_index
        Identifiability gate thresholds (module docstring); ``gate_sv = 0`` disables the gate.
    alert_k
        A change larger than ``alert_k`` standard deviations (and than the resolution) is a jump
        (:mod:`rivercal.online.guardrails`).
    loss, loss_scale
        Cost of the calibrations (:class:`~rivercal.problem.CalibrationProblem`): ``huber`` (default),
        ``student-t`` or ``l2`` (thesis Eq. 2-3), and its scale in σ (None: the loss's default).
    transition
        Run the transition estimator when an estimate jumps, and carry a transition it finds
        (:mod:`rivercal.online.intervention`); False: every jump raises an alert and the estimate creeps.
    transition_alpha, transition_min_reduction
        The transition test's significance level and smallest relative cost reduction
        (:func:`~rivercal.online.transition_search.transition_test`).
    transition_min_after_h
        A change is taken only when the window holds at least this many hours after it (at most half
        the window), h: a rain event
        whose inflow the model gets wrong makes the friction look changed while the flood passes, and
        an intervention stays (:mod:`rivercal.online.intervention`).
    skill_cycles, skill_lead_h, skill_tolerance
        Do no harm (:mod:`rivercal.online.skill`): the updated forecast is issued while its RMSE over the
        level forecasts up to ``skill_lead_h`` h of the last ``skill_cycles`` scored cycles is at most the
        DSS's times (1 + ``skill_tolerance``) (plus 1 mm); else the DSS's. ``skill_cycles = 0``: always the
        updated forecast.
    series
        Observed series to use (default: every series the model simulates that a station measures).
    sources
        Observation sources in priority order (default all).
    sigma
        σ per quantity or series id (default :data:`~rivercal.observations.DEFAULT_SIGMA`): m for levels, m³/s
        for discharges. Given as text (``"Q=50"``, ``"h=0.05,0040.Q=2"``), the quantities it leaves out keep
        their defaults. The weights of the calibrations (1/σ²) and the observation errors of the state
        analyses: a large river's discharges are not known to the default 0.1 m³/s.
    min_coverage
        A window whose observations cover less than this share of the hourly values raises a
        ``data`` alert; with none at all the cycle fails (and keeps the last estimate).
    output_interval_s
        Interval of the stored forecasts, s.
    dss
        Model quantities of the DSS (default: the model as it is).
    on_failure
        Failed model run inside a calibration: ``penalty`` (logged; the optimiser steers away) or
        ``raise`` (the cycle fails and keeps the last estimate).
    workers
        Worker processes of one calibration (None: all cores; at most the cores available,
        :func:`~rivercal.evaluate.check_workers`), or a :class:`~rivercal.evaluate.DaskCluster`.
    dependency, dependency_threshold
        With ``algorithm = "sparse_dud"``: a dependency map, the ``dependency.csv`` that ``rivercal analyse``
        writes (which series each parameter moves, in σ; :mod:`rivercal.analysis.dependency`), and the
        effect above which a dependency counts (σ). None: every series depends on every parameter.
    """

    parameters: tuple[str, ...] = ("FA", "Wd")
    window: str = "7D"
    period: str = "1D"
    horizon: str = "48h"
    warmup: str = "24h"
    algorithm: str = "dud"
    options: dict[str, Any] | None = None
    deadline_s: float | None = 60.0
    max_change: dict[str, float] = field(default_factory=dict)
    resolution: dict[str, float] = field(default_factory=dict)
    gate_sv: float = 1.0
    gate_index: float = 0.5
    alert_k: float = 3.0
    loss: str = "huber"
    loss_scale: float | None = None
    transition: bool = True
    transition_alpha: float = 1e-3
    transition_min_reduction: float = 0.25
    transition_min_after_h: float = 36.0
    skill_cycles: int = 3
    skill_lead_h: float = 24.0
    skill_tolerance: float = 0.0
    series: tuple[str, ...] | None = None
    sources: tuple[str, ...] | None = None
    sigma: dict[str, float] | None = None
    min_coverage: float = 0.8
    output_interval_s: float = 3600.0
    dss: dict[str, float] = field(default_factory=dict)
    on_failure: Literal["raise", "penalty"] = "penalty"
    workers: Workers = None
    dependency: str | None = None
    dependency_threshold: float = 0.1

    def __post_init__(self) -> None:
        for name in ("window", "period", "horizon"):
            _duration(name, getattr(self, name))
        _duration("warmup", self.warmup, zero=True)
        if not self.parameters:
            raise OnlineConfigError("parameters", "give at least one parameter to estimate")
        twice = sorted({n for n in self.parameters if list(self.parameters).count(n) > 1})
        if twice:
            raise OnlineConfigError("parameters", f"{twice[0]!r} is named twice", ",".join(self.parameters))
        from rivercal.optimise import OPTIMISERS
        from rivercal.optimise.registry import RENAMED

        if self.algorithm in RENAMED:
            raise OnlineConfigError("algorithm", f"it is now called {RENAMED[self.algorithm]}", self.algorithm)
        if self.algorithm not in OPTIMISERS:
            raise OnlineConfigError("algorithm", f"unknown optimiser; choose one of {', '.join(sorted(OPTIMISERS))}",
                                    self.algorithm)
        if self.deadline_s is not None:
            _number("deadline_s", self.deadline_s, above=0)
        for key, value in (self.sigma or {}).items():
            if not (math.isfinite(value) and value > 0):
                raise OnlineConfigError("sigma", f"the σ of {key} must be a positive number", f"{key}={value:g}")
            if "." not in key and key not in DEFAULT_SIGMA:
                raise OnlineConfigError("sigma", f"{key!r} is neither a quantity ({', '.join(DEFAULT_SIGMA)}) nor a "
                                                 "series id (STATION.QUANTITY)", f"{key}={value:g}")
        for name in ("max_change", "resolution"):
            for key, value in getattr(self, name).items():
                if key not in self.parameters:
                    raise OnlineConfigError(name, f"{key!r} is not among the estimated parameters "
                                                  f"({', '.join(self.parameters)})", f"{key}={value:g}")
                if not (math.isfinite(value) and value > 0):
                    raise OnlineConfigError(name, f"the value of {key} must be a positive number", f"{key}={value:g}")
        _number("alert_k", self.alert_k, above=0)
        _number("gate_sv", self.gate_sv, low=0)
        if not 0 < self.gate_index <= 1:
            raise OnlineConfigError("gate_index", "must be in (0, 1]", self.gate_index)
        if not 0 <= self.min_coverage <= 1:
            raise OnlineConfigError("min_coverage", "must be in [0, 1]", self.min_coverage)
        if self.on_failure not in ("raise", "penalty"):
            raise OnlineConfigError("on_failure", "must be 'raise' or 'penalty'", self.on_failure)
        if self.loss not in LOSSES:
            raise OnlineConfigError("loss", f"unknown loss; choose one of {', '.join(LOSSES)}", self.loss)
        if self.loss_scale is not None:
            _number("loss_scale", self.loss_scale, above=0)
        if not 0 < self.transition_alpha < 1:
            raise OnlineConfigError("transition_alpha", "must be in (0, 1)", self.transition_alpha)
        if not 0 <= self.transition_min_reduction < 1:
            raise OnlineConfigError("transition_min_reduction", "must be in [0, 1)", self.transition_min_reduction)
        _number("transition_min_after_h", self.transition_min_after_h, low=0)
        if self.dependency is not None and self.algorithm != "sparse_dud":
            raise OnlineConfigError("dependency", f"a dependency map serves the algorithm sparse_dud only, not "
                                                  f"{self.algorithm} (use sparse_dud, or no map)", self.dependency)
        _number("dependency_threshold", self.dependency_threshold, low=0)
        if isinstance(self.skill_cycles, bool) or int(self.skill_cycles) != self.skill_cycles or self.skill_cycles < 0:
            raise OnlineConfigError("skill_cycles", "must be a whole number, 0 or more", self.skill_cycles)
        _number("skill_lead_h", self.skill_lead_h, above=0)
        _number("skill_tolerance", self.skill_tolerance, low=0)
        _number("output_interval_s", self.output_interval_s, above=0)
        if not isinstance(self.workers, DaskCluster):
            try:
                check_workers(self.workers, "online workers")
            except ValueError as exc:
                raise OnlineConfigError("workers", str(exc).removeprefix("online workers: "), self.workers) from None

    # -- made from options, checked against a model ------------------------------------------------------

    @classmethod
    def from_options(cls, model: Model | None = None, **options: Any) -> OnlineConfig:
        """A configuration from options as a user gives them, checked (against ``model`` when given).

        ``options`` are fields of the class; ``parameters``, ``series`` and ``sources`` may be comma-separated
        text (``"FA,Wd"``), ``max_change`` and ``resolution`` text such as ``"FA=5,Wd=0.1"``, ``sigma`` text such as
        ``"Q=50"`` (over the defaults), numbers text.
        Options left out (or None, except those whose default is None) take the defaults.

        Raises
        ------
        OnlineConfigError
            Naming the field, the value and what is wrong.
        """
        known = {f.name: f for f in fields(cls)}
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise TypeError(f"unknown option(s) of the on-line configuration: {', '.join(unknown)}")
        values: dict[str, Any] = {}
        for name, value in options.items():
            if value is None and known[name].default is not None:
                continue
            if name in ("parameters", "series", "sources") and value is not None:
                value = _names(name, value)
            elif name in ("max_change", "resolution", "dss") and value is not None:
                value = _assignments(name, value)
            elif name == "sigma" and isinstance(value, str):
                value = {**DEFAULT_SIGMA, **_assignments(name, value)}
            elif name in _NUMBERS and isinstance(value, str):
                value = _number(name, value)
            values[name] = value
        config = cls(**values)
        if model is not None:
            config.check_model(model)
        return config

    def check_model(self, model: Model) -> None:
        """The configuration against a model: its parameters, the quantities they set, a dependency map.

        Raises
        ------
        OnlineConfigError
            For a parameter the model does not define, two parameters that set one quantity, or a dependency
            map that cannot be read or names none of the parameters.
        """
        from rivercal.parameters import shared_quantity

        known = model.calibration.names
        unknown = [n for n in self.parameters if n not in known]
        if unknown:
            raise OnlineConfigError("parameters", f"unknown parameter {unknown[0]!r}; {model.name!r} defines "
                                                  f"{', '.join(known) or 'none'}", ",".join(self.parameters))
        shared = shared_quantity(model.calibration.parameter(n) for n in self.parameters)
        if shared is not None:
            raise OnlineConfigError("parameters", f"{shared[0]} and {shared[1]} both set {shared[2]}; give only one "
                                                  "of them", ",".join(self.parameters))
        if self.dependency is not None:
            from rivercal.analysis.dependency import DependencyMap

            try:
                named = list(DependencyMap.from_csv(self.dependency, self.dependency_threshold).effects.columns)
            except ValueError as exc:
                raise OnlineConfigError("dependency", str(exc), self.dependency) from None
            if not set(named) & set(self.parameters):
                raise OnlineConfigError("dependency", f"the map names none of the parameters estimated "
                                                      f"({', '.join(self.parameters)}); it names {', '.join(named)}",
                                        self.dependency)

    def schedule(self, first_issue: Any) -> Schedule:
        """The cycle schedule whose cycle 0 is issued at ``first_issue``."""
        return Schedule(first_issue=first_issue, period=pd.Timedelta(self.period), window=pd.Timedelta(self.window),
                        horizon=pd.Timedelta(self.horizon))

    def stored(self) -> dict[str, Any]:
        """The configuration as stored with the run (JSON types; the worker count is not part of it)."""
        out = asdict(replace(self, workers=None))  # the workers may be a Dask cluster, which is not copied
        out.pop("workers")
        out["parameters"] = list(self.parameters)
        out["series"] = list(self.series) if self.series is not None else None
        out["sources"] = list(self.sources) if self.sources is not None else None
        if self.dependency is None:  # as runs stored before the map existed: they resume unchanged
            del out["dependency"], out["dependency_threshold"]
        return out


#: How :func:`check_schedule` names each setting by default (the command line passes its option names).
SETTING_NAMES = {"window": "window", "period": "period", "horizon": "horizon", "warmup": "warmup",
                 "first": "first issue", "last": "last issue"}


def span(value: Any) -> str:
    """A duration as text that pandas reads back: '7D', '48h', '58D23h', '90min', '45s' ('0h' for none)."""
    seconds = round(pd.Timedelta(value).total_seconds())
    if seconds == 0:
        return "0h"
    sign, seconds = ("-", -seconds) if seconds < 0 else ("", seconds)
    if seconds % 86400 and seconds % 3600 == 0 and seconds < 3 * 86400:
        return f"{sign}{seconds // 3600}h"  # 36h, 48h: as forecasters say them
    parts = []
    for unit, size in (("D", 86400), ("h", 3600), ("min", 60), ("s", 1)):
        if seconds >= size:
            parts.append(f"{seconds // size}{unit}")
            seconds %= size
    return sign + "".join(parts)


def check_schedule(model: Model, config: OnlineConfig, first: Any, last: Any | None = None, *,
                   names: Mapping[str, str] | None = None, shown: Mapping[str, str] | None = None) -> None:
    """Check the times of a run of ``config`` on ``model`` from issue time ``first`` to ``last`` (UTC).

    - the window, the cycle (``period``) and the horizon are positive, and the warm-up not negative, whole
      numbers of the output interval (``config.output_interval_s``): every run the service makes is;
    - cycles are issued at the model's output times (whole output intervals after its start);
    - the first window with its warm-up starts inside the model's period, the last issue time does not
      lie after its end, and the last cycle's forecast ends inside it: the model's forcing ends there, so
      a forecast beyond it would run on made-up forcing (the Delft-FEWS module refuses it too).

    Parameters
    ----------
    model
        The model (:mod:`rivercal.models.contract`): its ``start`` and ``end``.
    config
        The service configuration.
    first, last
        Issue times of the first and the last cycle (None: the last is not known yet).
    names
        How messages name each setting (keys of :data:`SETTING_NAMES`), e.g. ``{"period": "--cycle"}``.
    shown
        How messages show ``first`` and ``last`` (keys ``first``, ``last``), e.g. as the user wrote them.

    Raises
    ------
    ValueError
        Naming the setting, its value and the range it may take.
    """
    name = {**SETTING_NAMES, **(names or {})}
    step = pd.Timedelta(seconds=config.output_interval_s)
    grid = f"the service's time step ({span(step)}, the step of its forecasts and windows)"  # not the model's output
    start, end = utc(model.start), utc(model.end)
    length = end - start
    whose = "the case" if isinstance(model, FromCase) else "the model's period"
    values = {key: pd.Timedelta(getattr(config, key)) for key in ("window", "period", "horizon", "warmup")}
    for key, value in values.items():
        smallest = pd.Timedelta(0) if key == "warmup" else step
        if value < smallest or value % step:
            lower = (value // step) * step
            near = sorted({span(v) for v in (lower, lower + step) if v >= smallest})
            raise ValueError(f"{name[key]} {getattr(config, key)}: must be a whole number of {grid}, "
                             f"{'0 or more' if key == 'warmup' else 'at least one'}; e.g. {' or '.join(near)}")
    if values["window"] + values["warmup"] < values["period"]:
        # a cycle's run starts at its window's warm-up, from the state the cycle before saved one cycle after
        # its own run start: that moment must not lie after the issue time
        raise ValueError(f"{name['window']} {config.window}: with the warm-up ({span(values['warmup'])}) shorter "
                         f"than the cycle ({name['period']} {config.period}); each cycle starts from the state the "
                         f"cycle before saved one cycle after the start of its warm-up, so the window and its "
                         f"warm-up must span at least one cycle: lengthen {name['warmup']} to "
                         f"{span(values['period'] - values['window'])} or more, or shorten {name['period']}")
    if values["period"] > length:
        raise ValueError(f"{name['period']} {config.period}: longer than {whose} ({span(length)}); give "
                         f"{span(step)} to {span((length // step) * step)}")
    first = utc(first)
    text = {"first": _when(first), **({"last": _when(utc(last))} if last is not None else {}), **(shown or {})}
    if (first - start) % step:
        before = start + ((first - start) // step) * step
        raise ValueError(f"{name['first']} {text['first']}: cycles are issued on the service's time step, every "
                         f"{span(step)} from {start:%Y-%m-%d %H:%M}; e.g. {before:%Y-%m-%d %H:%M} or "
                         f"{before + step:%Y-%m-%d %H:%M}")
    need = values["window"] + values["warmup"]
    if need > length - step:
        longest = ((length - step - values["warmup"]) // step) * step
        raise ValueError(f"{name['window']} {config.window}: with the warm-up ({span(values['warmup'])}) longer than "
                         f"{whose} ({span(length)}) allows"
                         + (f"; give {span(step)} to {span(longest)}" if longest >= step else
                            f"; shorten {name['warmup']}"))
    if first - need < start:
        room = ((first - start - values["warmup"]) // step) * step
        shorter = f", or shorten {name['window']} to at most {span(room)}" if room >= step else ""
        raise ValueError(f"{name['first']} {text['first']}: the first window ({span(values['window'])}) and its "
                         f"warm-up ({span(values['warmup'])}) need the model from {first - need:%Y-%m-%d %H:%M}, "
                         f"before {whose} starts ({start:%Y-%m-%d %H:%M}); issue the first cycle at "
                         f"{start + need:%Y-%m-%d %H:%M} or later{shorter}")
    if first > end:
        raise ValueError(f"{name['first']} {text['first']}: after the end of {whose} ({end:%Y-%m-%d %H:%M})")
    if last is None:
        return
    last = utc(last)
    if last > end:
        raise ValueError(f"{name['last']} {text['last']}: after the end of {whose} ({end:%Y-%m-%d %H:%M})")
    final = first + ((last - first) // values["period"]) * values["period"] if last >= first else first
    if final + values["horizon"] > end:
        longest = ((end - final) // step) * step
        latest = end - values["horizon"]
        ways = [f"the horizon can be {span(step)} to {span(longest)}"] if longest >= step else []
        if final == first:  # one cycle
            which = "the cycle" if name["first"] == name["last"] else f"the cycle ({name['first']} and {name['last']})"
        else:
            which = f"the last cycle ({name['last']})" if latest >= first else \
                f"every cycle ({name['first']} and {name['last']})"
        ways.append(f"issue {which} at {latest:%Y-%m-%d %H:%M} or earlier")
        cycle = "the cycle" if final == first else "the last cycle"
        raise ValueError(f"{name['horizon']} {config.horizon}: {cycle}, issued at {final:%Y-%m-%d %H:%M}, "
                         f"would forecast to {final + values['horizon']:%Y-%m-%d %H:%M}, after the end of {whose} "
                         f"({end:%Y-%m-%d %H:%M}), where its forcing ends; " + ", or ".join(ways))


#: Fields that hold a number (given as text, they are read as one).
_NUMBERS = ("deadline_s", "alert_k", "gate_sv", "gate_index", "loss_scale", "transition_alpha",
            "transition_min_reduction", "transition_min_after_h", "skill_cycles", "skill_lead_h", "skill_tolerance",
            "min_coverage", "output_interval_s", "dependency_threshold")


def _duration(name: str, value: Any, *, zero: bool = False) -> pd.Timedelta:
    """A duration field, checked: positive (``zero``: zero or more).

    A bare number has no unit and is refused: pandas would read ``24`` as 24 nanoseconds, which nobody means.
    """
    if _bare_number(value):
        raise OnlineConfigError(name, "a duration needs its unit (e.g. 24h, 7D, 90min)", value)
    try:
        out = pd.Timedelta(value)
    except (ValueError, TypeError, OverflowError):
        out = None
    if out is None or pd.isna(out) or out < pd.Timedelta(0) or (out == pd.Timedelta(0) and not zero):
        raise OnlineConfigError(name, f"not a {'duration of zero or more' if zero else 'positive duration'} (e.g. "
                                      f"{'24h, 0h' if zero else '7D, 48h, 90min'})", value)
    return out


def _bare_number(value: Any) -> bool:
    """Whether ``value`` is a number without a unit (an int, a float, or text such as ``"24"`` or ``" 1.5 "``)."""
    if isinstance(value, bool):
        return False
    if isinstance(value, int | float):
        return True
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return False
        return True
    return False


def _number(name: str, value: Any, *, above: float | None = None, low: float | None = None) -> float:
    """A number field (text is read), finite, and above ``above`` or at least ``low``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise OnlineConfigError(name, "not a number", value) from None
    if not math.isfinite(number):
        raise OnlineConfigError(name, "must be a finite number", value)
    if above is not None and not number > above:
        raise OnlineConfigError(name, f"must be above {above:g}", value)
    if low is not None and number < low:
        raise OnlineConfigError(name, f"must be {low:g} or more", value)
    return int(number) if name == "skill_cycles" and number == int(number) else number


def _names(name: str, value: str | Iterable[str]) -> tuple[str, ...]:
    """'FA, Wd' or ['FA', 'Wd'] → ('FA', 'Wd'): blanks dropped, no name twice."""
    items = value.split(",") if isinstance(value, str) else list(value)
    names = tuple(str(n).strip() for n in items if str(n).strip())
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise OnlineConfigError(name, f"{twice[0]!r} is named twice", value if isinstance(value, str) else None)
    return names


def _assignments(name: str, value: str | Mapping[str, Any]) -> dict[str, float]:
    """'FA=5,Wd=0.1' (or a mapping) → {'FA': 5.0, 'Wd': 0.1}: finite numbers, each name once."""
    if not isinstance(value, str):
        return {str(k): float(v) for k, v in dict(value).items()}
    out: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in value.split(","))):
        key, sep, number = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise OnlineConfigError(name, "expected NAME=VALUE, e.g. FA=5,Wd=0.1", item)
        try:
            out_value = float(number)
        except ValueError:
            raise OnlineConfigError(name, f"{number.strip()!r} is not a number", item) from None
        if not math.isfinite(out_value):
            raise OnlineConfigError(name, "the value must be a finite number", item)
        if key in out:
            raise OnlineConfigError(name, f"{key!r} is given twice", item)
        out[key] = out_value
    return out


def _when(time: pd.Timestamp) -> str:
    """A time for messages, to the minute (to the second where it has seconds)."""
    return f"{time:%Y-%m-%d %H:%M}" if time.second == 0 and time.microsecond == 0 else f"{time:%Y-%m-%d %H:%M:%S}"
