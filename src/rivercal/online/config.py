"""The configuration of the on-line service (:class:`OnlineConfig`), stored with its run.

:func:`check_schedule` checks the times of a run against its model before anything runs: the window,
the cycle, the horizon and the warm-up are whole numbers of the output interval, cycles are issued at the
model's output times, and every window and forecast lies inside the model's period.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Literal

import pandas as pd

from rivercal._time import utc
from rivercal.evaluate import DaskCluster, Workers, check_workers
from rivercal.problem import LOSSES
from rivercal.store import Schedule

__all__ = ["DEFAULT_RESOLUTION", "SETTING_NAMES", "OnlineConfig", "check_schedule", "span"]


#: Resolution d of the identifiability gate and alert floor for the parameters of the packaged cases,
#: by unit (the smallest change that matters in operation).
DEFAULT_RESOLUTION = {"m^(1/3)/s": 0.5, "m AD": 0.01, "m": 0.01, "-": 0.01}


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
        missing: from :data:`DEFAULT_RESOLUTION` by unit, else 1 % of the range.
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
        σ per quantity or series id (default :data:`~rivercal.observations.DEFAULT_SIGMA`).
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
            if not pd.Timedelta(getattr(self, name)) > pd.Timedelta(0):
                raise ValueError(f"online {name} must be positive, got {getattr(self, name)!r}")
        if pd.Timedelta(self.warmup) < pd.Timedelta(0):
            raise ValueError(f"online warmup must not be negative, got {self.warmup!r}")
        if not self.parameters:
            raise ValueError("online: give at least one parameter to estimate")
        if self.deadline_s is not None and not self.deadline_s > 0:
            raise ValueError(f"online deadline_s must be positive, got {self.deadline_s}")
        for name, value in {**self.max_change, **self.resolution}.items():
            if not value > 0:
                raise ValueError(f"online: the change bound or resolution of {name} must be positive, got {value}")
        if not self.alert_k > 0 or self.gate_sv < 0 or not 0 < self.gate_index <= 1:
            raise ValueError("online: alert_k must be > 0, gate_sv >= 0 and gate_index in (0, 1]")
        if not 0 <= self.min_coverage <= 1:
            raise ValueError(f"online min_coverage must be in [0, 1], got {self.min_coverage}")
        if self.on_failure not in ("raise", "penalty"):
            raise ValueError(f"online on_failure must be 'raise' or 'penalty', got {self.on_failure!r}")
        if self.loss not in LOSSES:
            raise ValueError(f"online loss must be one of {', '.join(LOSSES)}, got {self.loss!r}")
        if self.loss_scale is not None and not self.loss_scale > 0:
            raise ValueError(f"online loss_scale must be positive, got {self.loss_scale}")
        if not 0 < self.transition_alpha < 1 or not 0 <= self.transition_min_reduction < 1:
            raise ValueError("online: transition_alpha must be in (0, 1) and transition_min_reduction in [0, 1)")
        if not self.transition_min_after_h >= 0:
            raise ValueError(f"online: transition_min_after_h must be >= 0, got {self.transition_min_after_h}")
        if self.dependency is not None and self.algorithm != "sparse_dud":
            raise ValueError(f"online: a dependency map serves Sparse DuD only; the algorithm is {self.algorithm!r} "
                             "(use 'sparse_dud', or no map)")
        if not self.dependency_threshold >= 0:
            raise ValueError(f"online dependency_threshold must be >= 0 (σ), got {self.dependency_threshold}")
        if self.skill_cycles < 0 or not self.skill_lead_h > 0 or self.skill_tolerance < 0:
            raise ValueError("online: skill_cycles must be >= 0, skill_lead_h > 0 and skill_tolerance >= 0")
        if not self.output_interval_s > 0:
            raise ValueError(f"online output_interval_s must be positive, got {self.output_interval_s}")
        if not isinstance(self.workers, DaskCluster):
            check_workers(self.workers, "online workers")

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


def check_schedule(model: Any, config: OnlineConfig, first: Any, last: Any | None = None, *,
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
    grid = f"the output interval ({span(step)})"
    start, end = utc(model.start), utc(model.end)
    length = end - start
    whose = "the case" if getattr(model, "case", None) is not None else "the model's period"
    values = {key: pd.Timedelta(getattr(config, key)) for key in ("window", "period", "horizon", "warmup")}
    for key, value in values.items():
        smallest = pd.Timedelta(0) if key == "warmup" else step
        if value < smallest or value % step:
            lower = (value // step) * step
            near = sorted({span(v) for v in (lower, lower + step) if v >= smallest})
            raise ValueError(f"{name[key]} {getattr(config, key)}: must be a whole number of {grid}, "
                             f"{'0 or more' if key == 'warmup' else 'at least one'}; e.g. {' or '.join(near)}")
    if values["period"] > length:
        raise ValueError(f"{name['period']} {config.period}: longer than {whose} ({span(length)}); give "
                         f"{span(step)} to {span((length // step) * step)}")
    first = utc(first)
    text = {"first": _when(first), **({"last": _when(utc(last))} if last is not None else {}), **(shown or {})}
    if (first - start) % step:
        before = start + ((first - start) // step) * step
        raise ValueError(f"{name['first']} {text['first']}: cycles are issued at the model's output times, every "
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
        which = f"the last cycle ({name['last']})" if latest >= first else \
            f"every cycle ({name['first']} and {name['last']})"
        ways.append(f"issue {which} at {latest:%Y-%m-%d %H:%M} or earlier")
        raise ValueError(f"{name['horizon']} {config.horizon}: the last cycle, issued at {final:%Y-%m-%d %H:%M}, "
                         f"would forecast to {final + values['horizon']:%Y-%m-%d %H:%M}, after the end of {whose} "
                         f"({end:%Y-%m-%d %H:%M}), where its forcing ends; " + ", or ".join(ways))


def _when(time: pd.Timestamp) -> str:
    """A time for messages, to the minute (to the second where it has seconds)."""
    return f"{time:%Y-%m-%d %H:%M}" if time.second == 0 and time.microsecond == 0 else f"{time:%Y-%m-%d %H:%M:%S}"
