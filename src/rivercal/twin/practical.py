"""The practical-implication scenarios of thesis chapter 5: a truth whose parameters change suddenly.

On 2010-11-01 00:00 UTC (thesis §5-1) somebody intervenes in the river: vegetation is mowed or crests are
lowered. Before the change the truth is the DSS itself (the case's own parameter values); after it one
of these holds (thesis §5-2):

=======  ===========================================================  ==========================
name     after the change                                             rivercal can represent it
=======  ===========================================================  ==========================
PI-0     nothing changes                                              (nothing to represent)
PI-Fg    global Strickler k_s 16 → 25 m^(1/3)/s (mowing everywhere)   FA = 25
PI-Wg    the nine adjustable crests all 0.15 m lower                   Wd = −0.15 m
PI-Fl    k_s of branch Nriv_ZL_1_9820 → 25 m^(1/3)/s, the rest 16      FL = 25 (not FA or Wd)
PI-Wl    crest of weir ZL1-5930 0.15 m lower                           W4 = 6.995 m AD
PI-SF    (dommel-controlled) W2's target level 0.10 m higher and       FA = 19.2 and S2 = 10.66
         global k_s 16 → 19.2 m^(1/3)/s, both at once
=======  ===========================================================  ==========================

The changes are written relative to the model's defaults (the DSS): a friction is set to a value, a crest
is shifted from its DSS level, so the same scenario applies to any case that has these branches and weirs.
The on-line service estimates FA (``friction:global``) and Wd (all adjustable crests shifted alike) by
default; each scenario records the true values of these two where they exist, and of FL (the friction of
Nriv_ZL_1_9820, a parameter of the dommel case for this scenario) in PI-Fl. In PI-Fl the
global friction stays 16, so FA's truth exists, but neither FA nor Wd can represent the change. In PI-Wl
the crests do not move alike, so Wd has no true value.

:func:`practical_truth` runs the truth in one pass from the model's own start (cold start and spin-up)
with the "before" values up to the change and the "after" values from there, hot-starting each leg from
the state the previous one ended in; the model is never restarted inside the period.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.models.capabilities import capability
from rivercal.models.contract import Model, ModelState, spun_up
from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet, measurable
from rivercal.twin.noise import NOISE_MODELS, add_noise
from rivercal.twin.realism import REALISM_LEVELS, Realism, apply_sensor_errors, get_realism
from rivercal.twin.truth_model import truth_model

__all__ = [
    "ADJUSTABLE_WEIRS",
    "CHANGE_TIME",
    "CONTROLLED_SCENARIOS",
    "LOCAL_BRANCH",
    "LOCAL_WEIR",
    "PRACTICAL_SCENARIOS",
    "SCENARIOS",
    "PracticalScenario",
    "PracticalTruth",
    "QuantityChange",
    "practical_truth",
]

#: The moment of the intervention in every scenario (thesis §5-1), UTC.
CHANGE_TIME = pd.Timestamp("2010-11-01T00:00:00Z")

#: The nine adjustable weirs W1…W9 of the dommel case (thesis Table 4-2), the targets of Wc and Wd.
ADJUSTABLE_WEIRS = ("ZL1-5", "ZL1-3014", "ZL1-5126", "ZL1-5930", "ZL12-45", "ZL12-1880", "ZL12-4711",
                    "ZL25-6292", "ZL25-8463")

#: The section whose friction changes in PI-Fl, and the weir whose crest changes in PI-Wl (thesis Fig. 5-1).
LOCAL_BRANCH = "Nriv_ZL_1_9820"
LOCAL_WEIR = "ZL1-5930"
#: The weir whose target level changes in PI-SF, and its controller in the case dommel-controlled.
SETPOINT_WEIR = "ZL1-3014"
SETPOINT_CONTROLLER = "W2"


@dataclass(frozen=True)
class QuantityChange:
    """One model quantity of a scenario, relative to the model's default (the DSS).

    Attributes
    ----------
    target
        Model quantity (``friction:global``, ``friction:branch:<id>``, ``weir:<id>.crest_level``).
    value
        Absolute value to set (k_s in m^(1/3)/s, crest in m AD), or None.
    shift
        Amount added to the model's default value (m for crests), or None. Exactly one of ``value`` and
        ``shift`` is given.
    """

    target: str
    value: float | None = None
    shift: float | None = None

    def __post_init__(self) -> None:
        if (self.value is None) == (self.shift is None):
            raise ValueError(f"{self.target}: give exactly one of value and shift "
                             f"(got value={self.value}, shift={self.shift})")

    def resolve(self, defaults: Mapping[str, float]) -> float:
        """The absolute value of the quantity for a model with these defaults (targets → values).

        Raises
        ------
        KeyError
            When the change is a shift and the model has no default for the target.
        """
        if self.value is not None:
            return float(self.value)
        if self.target not in defaults:
            raise KeyError(f"{self.target}: the model has no such quantity to shift by {self.shift:+g}")
        return float(defaults[self.target]) + float(self.shift)  # type: ignore[arg-type]


@dataclass(frozen=True)
class PracticalScenario:
    """A truth whose model quantities change at one moment (thesis §5-2).

    Attributes
    ----------
    name
        ``PI-0``, ``PI-Fg``, ``PI-Wg``, ``PI-Fl``, ``PI-Wl`` or ``PI-SF``.
    description
        One line for reports.
    change_time
        Moment of the change (UTC).
    before, after
        Changes to the model's defaults before and after ``change_time`` (empty: the DSS itself).
    represented_by
        Names of the dommel case's parameters that could represent the change exactly (empty when none can).
    true_before, true_after
        True values of the on-line service's parameters FA (k_s, m^(1/3)/s) and Wd (crest shift from the
        DSS, m) before and after the change; None where the truth is not of that form. PI-Fl also gives FL
        (k_s of Nriv_ZL_1_9820, m^(1/3)/s).
    """

    name: str
    description: str
    change_time: pd.Timestamp
    before: tuple[QuantityChange, ...]
    after: tuple[QuantityChange, ...]
    represented_by: tuple[str, ...]
    true_before: dict[str, float | None] = field(hash=False)
    true_after: dict[str, float | None] = field(hash=False)

    def quantities(self, defaults: Mapping[str, float], *, after: bool) -> dict[str, float]:
        """The model quantities (targets → values) that differ from ``defaults`` before or after the change.

        ``defaults`` are the model's own values, e.g. ``model.default_parameters()``. Targets not listed
        keep the model's values, so the dict can be passed to ``model.simulate`` as it is.
        """
        changes = self.after if after else self.before
        return {c.target: c.resolve(defaults) for c in changes}

    def facts(self) -> dict[str, Any]:
        """What a run's ``meta["truth"]`` keeps of the scenario for its metrics: the change time and the true values.

        The on-line service reads them there (:class:`rivercal.online.metrics.ChangeFacts`), so that its run
        metrics know the truth of a twin without the twin package.
        """
        return {"change_time": utc(self.change_time).isoformat(), "true_before": dict(self.true_before),
                "true_after": dict(self.true_after)}


def _dss() -> dict[str, float | None]:
    return {"FA": 16.0, "Wd": 0.0}


def _scenarios() -> dict[str, PracticalScenario]:
    crests_down = tuple(QuantityChange(f"weir:{w}.crest_level", shift=-0.15) for w in ADJUSTABLE_WEIRS)
    items = [
        PracticalScenario("PI-0", "no change: the truth is the DSS throughout", CHANGE_TIME, (), (), (),
                          _dss(), _dss()),
        PracticalScenario("PI-Fg", "global friction k_s 16 → 25 m^(1/3)/s (vegetation mowed everywhere)",
                          CHANGE_TIME, (), (QuantityChange("friction:global", value=25.0),), ("FA",),
                          _dss(), {"FA": 25.0, "Wd": 0.0}),
        PracticalScenario("PI-Wg", "all nine adjustable crests lowered by 0.15 m", CHANGE_TIME, (), crests_down,
                          ("Wd",), _dss(), {"FA": 16.0, "Wd": -0.15}),
        PracticalScenario("PI-Fl", f"k_s of section {LOCAL_BRANCH} 16 → 25 m^(1/3)/s, the rest stays 16",
                          CHANGE_TIME, (), (QuantityChange(f"friction:branch:{LOCAL_BRANCH}", value=25.0),), ("FL",),
                          {**_dss(), "FL": 16.0}, {"FA": 16.0, "Wd": 0.0, "FL": 25.0}),
        PracticalScenario("PI-Wl", f"crest of weir {LOCAL_WEIR} lowered by 0.15 m", CHANGE_TIME, (),
                          (QuantityChange(f"weir:{LOCAL_WEIR}.crest_level", shift=-0.15),), ("W4",),
                          _dss(), {"FA": 16.0, "Wd": None}),
    ]
    return {s.name: s for s in items}


#: The scenarios of thesis chapter 5 by name.
PRACTICAL_SCENARIOS: dict[str, PracticalScenario] = _scenarios()


def _controlled() -> dict[str, PracticalScenario]:
    items = [
        PracticalScenario("PI-SF", f"controlled case: the target level of weir {SETPOINT_WEIR} raised by 0.10 m while "
                          "the global friction k_s rises 16 → 19.2 m^(1/3)/s (20 %)", CHANGE_TIME, (),
                          (QuantityChange(f"control:{SETPOINT_CONTROLLER}.setpoint", shift=0.10),
                           QuantityChange("friction:global", value=19.2)), ("FA", "S2"),
                          {"FA": 16.0, "S2": 10.56}, {"FA": 19.2, "S2": 10.66}),
    ]
    return {s.name: s for s in items}


#: Scenarios of the controlled case (dommel-controlled) by name.
CONTROLLED_SCENARIOS: dict[str, PracticalScenario] = _controlled()
#: Every scenario by name: those of thesis chapter 5 and those of the controlled case.
SCENARIOS: dict[str, PracticalScenario] = {**PRACTICAL_SCENARIOS, **CONTROLLED_SCENARIOS}


@dataclass(frozen=True)
class PracticalTruth:
    """The truth of a practical scenario over a period.

    Attributes
    ----------
    scenario
        The scenario.
    observations
        The observed series in [start, end] at the output interval (with noise when asked); ``source`` names
        the scenario. Levels in m AD, discharges in m³/s.
    series
        The noise-free truth of every observable in [start, end].
    levels
        Noise-free levels, m AD, at every calculation point (columns ``compiled.hp_label``) in [start, end],
        or None when not asked for.
    state
        The truth's engine state at ``start`` (to hot-start runs there), or None when ``start`` is the model's
        own start (a cold start).
    start, end
        The period (UTC).
    change_time
        Moment of the change (UTC).
    before, after
        Model quantities (targets → values) that differ from the model's defaults before and after the change.
    true_before, true_after
        True FA (m^(1/3)/s) and Wd (m) before and after the change, None where they do not exist.
    realism
        The realism level of the truth and the observations.
    error_kinds
        What each observed value is (``ok``, ``outlier``, ``gap``, ``drift``), same shape as the observed
        series; None when not made.
    """

    scenario: PracticalScenario
    observations: ObservationSet
    series: pd.DataFrame
    levels: pd.DataFrame | None
    state: ModelState | None
    start: pd.Timestamp
    end: pd.Timestamp
    change_time: pd.Timestamp
    before: dict[str, float]
    after: dict[str, float]
    true_before: dict[str, float | None]
    true_after: dict[str, float | None]
    realism: Realism = field(default_factory=lambda: REALISM_LEVELS["ideal"])
    error_kinds: pd.DataFrame | None = None


def _on_grid(what: str, t: pd.Timestamp, origin: pd.Timestamp, interval: float) -> None:
    steps = (t - origin).total_seconds() / interval
    if abs(steps - round(steps)) > 1e-9:
        raise ValueError(f"{what} {t.isoformat()} is not on the {interval:g} s output grid that starts at the "
                         f"model start {origin.isoformat()}")


def _on_model_grid(model: Model, span: pd.Timedelta) -> bool:
    """Whether ``span`` from the model's start is a whole number of the model's own output intervals."""
    step = float(getattr(model, "output_interval", 0.0) or 0.0)
    return step > 0 and span.total_seconds() % step == 0


def _legs(model_start: pd.Timestamp, start: pd.Timestamp, end: pd.Timestamp,
          change: pd.Timestamp) -> list[tuple[pd.Timestamp, pd.Timestamp, bool]]:
    """The runs (from, to, after the change?) from the model start to ``end``, cut at ``start`` and the change."""
    cuts = sorted({t for t in (start, change) if model_start < t < end})
    edges = [model_start, *cuts, end]
    return [(a, b, a >= change) for a, b in pairwise(edges)]


def practical_truth(model: Model, scenario: str | PracticalScenario, start: Any, end: Any, *, noise: str = "none",
                    seed: int = 0, sigma: Mapping[str, float | None] | None = None,
                    series: Sequence[str] | None = None, output_interval: float = 3600.0,
                    levels: bool = False, realism: str | Realism | None = None) -> PracticalTruth:
    """Run the truth of a practical scenario and make its observations.

    Parameters
    ----------
    model
        A model of the model contract (:mod:`rivercal.models.contract`); with ``levels``, one with snapshots
        (e.g. the embedded engine).
    scenario
        A name of :data:`SCENARIOS` or a scenario (e.g. one with another ``change_time``).
    start, end
        The period of the observations (UTC; naive times are taken as UTC). It must lie inside the
        model's period and on its output grid; it may lie entirely before or after the change.
    noise, seed
        Noise model of :mod:`rivercal.twin.noise` and its seed (the same seed gives the same noise and the
        same errors of ``realism``).
    sigma
        σ per quantity or series id for the observation weights (default
        :data:`~rivercal.observations.DEFAULT_SIGMA`: 0.025 m for levels, 0.1 m³/s for discharges).
    series
        Series ids to observe (default: every series of the model that a station measures).
    output_interval
        Interval of the truth and the observations, s (default hourly).
    levels
        Also return the levels at every calculation point (for the network maps of thesis Figs. 5-2 … 5-15).
    realism
        A realism level of :mod:`rivercal.twin.realism` (name, TOML file or :class:`Realism`): the truth runs
        with its rainfall, runoff and structural errors (:func:`~rivercal.twin.truth_model.truth_model`) and
        the observations carry its sensor errors. None or ``ideal``: the identical twin. It does not combine
        with ``noise``.

    Returns
    -------
    PracticalTruth

    Raises
    ------
    KeyError
        For an unknown scenario or series id.
    ValueError
        For an unknown noise model, a period outside the model's or off its output grid, or end ≤ start.

    Examples
    --------
    >>> from rivercal.model import load_model
    >>> from rivercal.twin.practical import practical_truth
    >>> truth = practical_truth(load_model("dommel"), "PI-Fg", "2010-10-30", "2010-11-02")
    >>> truth.true_before, truth.true_after
    ({'FA': 16.0, 'Wd': 0.0}, {'FA': 25.0, 'Wd': 0.0})
    >>> truth.observations
    ObservationSet(11 series, 803 values 2010-10-30 00:00 … 2010-11-02 00:00 UTC, 0 missing)
    """
    if isinstance(scenario, str):
        if scenario not in SCENARIOS:
            raise KeyError(f"unknown practical scenario {scenario!r}; choose one of {', '.join(SCENARIOS)}")
        scenario = SCENARIOS[scenario]
    if noise not in NOISE_MODELS:
        raise ValueError(f"unknown noise model {noise!r}; choose one of {', '.join(NOISE_MODELS)}")
    level = get_realism(realism) if realism is not None else REALISM_LEVELS["ideal"]
    if noise != "none" and not level.ideal:
        raise ValueError(f"noise {noise!r} and realism {level.name!r} both add observation errors; choose one")
    truth_of = truth_model(model, level, seed)
    start, end, change = utc(start), utc(end), utc(scenario.change_time)
    model_start, model_end = utc(model.start), utc(model.end)
    if not end > start:
        raise ValueError(f"end {end.isoformat()} must be after start {start.isoformat()}")
    if start < model_start or end > model_end:
        raise ValueError(f"period {start.isoformat()} … {end.isoformat()} lies outside the model's period "
                         f"{model_start.isoformat()} … {model_end.isoformat()}")
    interval = float(output_interval)
    for what, t in (("start", start), ("end", end), ("change time", change)):
        if what != "change time" or model_start < t < end:
            _on_grid(what, t, model_start, interval)
    ids = list(series) if series is not None else measurable(model.observables)
    unknown = [s for s in ids if s not in model.observables]
    if unknown:
        raise KeyError(f"series {unknown[0]!r} is not simulated by the model (have: {', '.join(model.observables)})")

    defaults = model.default_parameters()
    values = {False: scenario.quantities(defaults, after=False), True: scenario.quantities(defaults, after=True)}
    state = start_state = None
    frames: list[pd.DataFrame] = []
    level_frames: list[pd.DataFrame] = []
    for a, b, after in _legs(model_start, start, end, change):
        keep = b > start
        if state is None and not keep and _on_model_grid(truth_of, b - model_start):
            state = spun_up(truth_of, values[after], b)   # a spin-up: the model may have run it before
            if b == start:
                start_state = state
            continue
        run = truth_of.simulate
        if levels and keep:  # the levels at every point: a model with snapshots
            run = capability(truth_of, "snapshots", purpose="the truth's levels at every point").simulate_fields
        result, state = run(values[after], a, b, state, output_interval=interval)
        if b == start:
            start_state = state
        if keep:
            skip = 1 if frames else 0  # the first row of a hot-started leg repeats the previous leg's last row
            frames.append(result.series.iloc[skip:])
            if levels:
                level_frames.append(result.levels.iloc[skip:])
    truth = pd.concat(frames).loc[start:end]
    level_frame = pd.concat(level_frames).loc[start:end] if levels else None

    sigma = dict(sigma if sigma is not None else DEFAULT_SIGMA)
    rng = np.random.default_rng(seed)
    errors = f"realism {level.name}" if not level.ideal else f"noise {noise}"
    source = f"practical scenario {scenario.name} (change {change:%Y-%m-%d %H:%M} UTC), {errors} (seed {seed})"
    frame = truth[ids]
    kinds = pd.DataFrame("ok", index=frame.index, columns=frame.columns)
    if level.sensor is not None:
        frame, kinds = apply_sensor_errors(frame, level.sensor, seed, model_start, interval)
    observed = []
    for sid in ids:
        quantity = sid.rpartition(".")[2]
        noisy = add_noise(frame[sid].to_numpy(), quantity, noise, rng)
        observed.append(ObservationSeries.from_series(pd.Series(noisy, index=truth.index), id=sid,
                                                      sigma=sigma.get(sid, sigma.get(quantity)), source=source))
    return PracticalTruth(
        scenario=scenario, observations=ObservationSet(tuple(observed)), series=truth, levels=level_frame,
        state=start_state, start=start, end=end, change_time=change, before=values[False], after=values[True],
        true_before=dict(scenario.true_before), true_after=dict(scenario.true_after), realism=level,
        error_kinds=kinds,
    )
