"""State updating for the on-line service: an ensemble Kalman filter over any model that can.

Modes (``--assimilate``): ``parameters`` — the daily parameter cycle alone (no ensemble); ``states`` —
the ensemble filter alone, with the model's (the DSS's) parameters; ``both`` — the daily parameter
cycle, and between cycles hourly state analyses with the parameters it accepted.

The filter sees the model only through the model contract (:mod:`rivercal.models.contract`). It needs two
optional capabilities: ``state arrays`` (the state as levels and discharges, read and written back:
:class:`~rivercal.models.capabilities.StateArrays`) and ``perturbable forcing`` (its inflows and laterals scaled
by factors: :class:`~rivercal.models.capabilities.PerturbableForcing`). A model without them is refused with an
error that names what it lacks (:class:`~rivercal.models.capabilities.MissingCapability`). The members run in
parallel: in one call of a model with ``ensemble runs`` (the embedded engine: threads, the compiled loop
releases the interpreter lock), else one run per member on the service's worker processes (SWMM, whose
engine keeps one project per process).

Each cycle issued at t₀ takes the members the previous cycle left at t₀ − period (hot start of all
members; a cold ensemble — copies of the updated model's state at the start of the window — for the
first cycle or when none is stored), and then per analysis interval

1. advances all members, each with its own inflows and laterals: the model's forcing times log-normal
   AR(1) factors (:mod:`rivercal.assimilate.perturb`; the model error — rain and runoff that were wrong);
2. analyses, at the interval's end, the levels and discharges of every point of the model's state, and the
   members' forcing errors (an augmented state: an error of the rain persists for hours, so the forecast gains
   from knowing it), with every reading inside the interval, at the sensors' own time stamps (every 10 or 31
   minutes, seconds off the minute): each reading is compared with the members' series interpolated to its
   time (:meth:`EnsembleFilter.assimilate`; the asynchronous EnKF, no reading is moved or dropped);
   :mod:`rivercal.assimilate.filters`, localised along the network with the Gaspari–Cohn taper, a forcing
   error at the point where it enters; and writes them back into the members' states (the model makes the
   rest of its state consistent with them).

From t₀ the members forecast the horizon with their forcing perturbed on; the forecast is the ensemble
mean, its 90 % band the 5 % and 95 % quantiles of the members' values plus the observation error (the
band is for the observations, which carry that error).
"""

from __future__ import annotations

import io
import logging
import math
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import pandas as pd

from rivercal.assimilate import FILTERS, gaspari_cohn, network_distances
from rivercal.assimilate.perturb import ar1_series, multiplicative_factors
from rivercal.errors import ModelRunError
from rivercal.evaluate import Tasks, Workers
from rivercal.models.capabilities import EnsembleRuns, MemberRuns, has_capability, require, run_members
from rivercal.models.contract import Model, ModelState
from rivercal.observations import DEFAULT_SIGMA
from rivercal.store import CycleSpec, Run, Store

if TYPE_CHECKING:
    from rivercal.online.service import OnlineService

__all__ = ["ASSIMILATE_MODES", "ISSUED", "NEEDS", "AssimilationConfig", "EnsembleFilter", "EnsembleForecast",
           "assimilation_cycle", "can_update_states", "default_mode"]

log = logging.getLogger(__name__)

#: The modes of the on-line service (module docstring).
ASSIMILATE_MODES = ("parameters", "states", "both")
#: The forecasts state updating can issue (:attr:`AssimilationConfig.issued`).
ISSUED = ("mean", "central")
#: The model capabilities state updating needs (:mod:`rivercal.models.capabilities`).
NEEDS = ("state arrays", "perturbable forcing")
#: Format tag of a stored ensemble: a zip archive with each member's state as the model saves it
#: (``members/0000`` …), the model's state format (``state-format.txt``) and the members' AR(1) forcing errors
#: (``errors.npy``, members × perturbed forcing).
ENSEMBLE_FORMAT = "rivercal-ensemble-zip-2"


def can_update_states(model: Model) -> bool:
    """Whether the model has what state updating needs (:data:`NEEDS`)."""
    try:
        require(model, *NEEDS, purpose="state updating")
    except ValueError:
        return False
    return True


def default_mode(model: Model) -> str:
    """The service's default: ``both`` where the model can update its states, else ``parameters``.

    Under realistic errors most of a forecast's error is in the state (wrong rain, wrong runoff), which no
    parameter estimate corrects; states and parameters together do (docs/realism.md).
    """
    return "both" if can_update_states(model) else "parameters"


@dataclass(frozen=True)
class AssimilationConfig:
    """How the ensemble filter runs (stored with the run).

    Attributes
    ----------
    mode
        ``parameters``, ``states`` or ``both`` (module docstring).
    members
        Ensemble size.
    method
        ``etkf`` (square root) or ``enkf`` (perturbed observations).
    interval
        Time between analyses (and the step of the forcing perturbations).
    inflation
        Multiplicative inflation of the forecast anomalies before each analysis (1: none).
    localisation_m
        Gaspari–Cohn half-width c along the network, m: an observation acts on points up to 2c away.
    forcing_error
        σ of the log of the factors on inflows and laterals (0.3: about 30 %).
    forcing_tau
        Correlation time of the forcing errors (and of the level boundaries' errors): 96 h, as much of a model's
        inflow error is a bias that persists for days (a catchment's runoff parameters, an event's rain); measured
        on the realistic PI-Fg twin,
        the issued forecasts' MAE ratio is 1.93 at 24 h, 2.11 at 48 h, 2.23 at 96 h and 2.27 at 168 h.
    level_error
        σ of the additive error of each level boundary (a tide at the mouth: the surge the tide prediction does not
        know), m; for a model with ``perturbable levels`` (:class:`~rivercal.models.capabilities.PerturbableLevels`).
        0.3 m is a choice, not a measured figure: set it to the size of the departures from the boundary's series
        that are expected (the Western Scheldt benchmark takes 0.5 m for a storm surge of up to 3 m).
    seed
        Seed of the perturbations (per cycle, the seed and the cycle number).
    threads
        Threads of a model that runs members in one call (None: all).
    issued
        The forecast issued (stored as ``updated``): ``mean``, the mean of the members' forecasts, or ``central``,
        one more run from the members' mean state with the forcing errors they are expected to have
        (:meth:`EnsembleFilter.expected_factors`). Where levels respond non-linearly to the inflow, the members'
        spread lowers their mean (a level rises less than in proportion to the discharge); the central run has
        no such bias. The 90 % band comes from the members either way.
    """

    mode: Literal["parameters", "states", "both"] = "parameters"
    members: int = 64
    method: Literal["etkf", "enkf"] = "etkf"
    interval: str = "1h"
    inflation: float = 1.0
    localisation_m: float = 20_000.0
    forcing_error: float = 0.3
    forcing_tau: str = "96h"
    level_error: float = 0.3
    seed: int = 0
    threads: int | None = None
    issued: Literal["mean", "central"] = "mean"

    def __post_init__(self) -> None:
        if self.mode not in ASSIMILATE_MODES:
            raise ValueError(f"assimilate mode must be one of {', '.join(ASSIMILATE_MODES)}, got {self.mode!r}")
        if self.method not in FILTERS:
            raise ValueError(f"assimilation method must be one of {', '.join(FILTERS)}, got {self.method!r}")
        if not 2 <= self.members <= 10_000:
            raise ValueError(f"ensemble members must be between 2 and 10000, got {self.members}")
        if not pd.Timedelta(self.interval) > pd.Timedelta(0) or not pd.Timedelta(self.forcing_tau) > pd.Timedelta(0):
            raise ValueError("the analysis interval and the forcing correlation time must be positive")
        if not self.inflation >= 1.0 or not self.localisation_m > 0 or not self.forcing_error >= 0:
            raise ValueError("inflation must be >= 1, the localisation half-width > 0 m and the forcing error >= 0")
        if not (math.isfinite(self.level_error) and self.level_error >= 0):
            raise ValueError(f"the level boundaries' error must be >= 0 m, got {self.level_error}")
        if self.issued not in ISSUED:
            raise ValueError(f"the issued forecast must be one of {', '.join(ISSUED)}, got {self.issued!r}")

    def stored(self) -> dict[str, Any]:
        """The configuration as stored with the run (the thread count is not part of it).

        ``level_error`` and ``issued`` are stored only when they are not the default, so that a run stored before
        level boundaries were perturbed, or before the issued forecast could be chosen, resumes with the same
        configuration.
        """
        out = asdict(self)
        out.pop("threads")
        for key in ("level_error", "issued"):
            if out[key] == getattr(AssimilationConfig, key):
                out.pop(key)
        return out


@dataclass(frozen=True)
class EnsembleForecast:
    """The forecast of an analysed ensemble per series (m AD or m³/s), UTC index.

    ``mean`` is the issued forecast (the members' mean or the central run, :attr:`AssimilationConfig.issued`),
    ``low`` … ``high`` the 90 % band.
    """

    mean: pd.DataFrame
    low: pd.DataFrame
    high: pd.DataFrame


class EnsembleFilter:
    """The ensemble filter of one run (module docstring).

    Parameters
    ----------
    model
        A model with the capabilities of :data:`NEEDS`.
    config
        The filter configuration.
    series
        Observed series the filter uses.
    sigma
        σ per quantity or series id (default :data:`~rivercal.observations.DEFAULT_SIGMA`), m or m³/s.
    workers
        Worker processes for the members of a model that cannot run them in one call (None: all cores),
        or a Dask cluster.

    Raises
    ------
    MissingCapability
        When the model lacks a capability of :data:`NEEDS`.
    ValueError
        When a series has no place in the model's network.
    """

    def __init__(self, model: Model, config: AssimilationConfig, series: list[str],
                 sigma: dict[str, float] | None = None, *, workers: Workers = None):
        require(model, *NEEDS, purpose="state updating (--assimilate states or both)")
        self.model = model
        self.config = config
        self.series = list(series)
        self.workers = workers
        self._tasks: Tasks | None = None
        # the last ensemble this filter wrote (its archive, members and errors): the next cycle of this process
        # takes the members as they are in memory when the store still holds that very archive
        self._kept: tuple[bytes, list[ModelState], np.ndarray] | None = None
        layout = model.state_layout()
        self.n_h, self.n_l = len(layout.levels), len(layout.discharges)
        col = {name: i for i, name in enumerate(model.observables)}
        self.columns = np.array([col[s] for s in self.series], dtype=np.int64)
        sig = {**DEFAULT_SIGMA, **(sigma or {})}  # a quantity left out keeps its default
        self.sigma = np.array([float(sig.get(s, sig.get(s.rpartition(".")[2]))) for s in self.series])
        unplaced = [s for s in self.series if s not in layout.places]
        if unplaced:
            raise ValueError(f"state updating: series {unplaced[0]!r} has no place in the state of model "
                             f"{getattr(model, 'name', '?')!r}")
        place = np.array([layout.places[s] for s in self.series], dtype=np.int64)
        ends = np.asarray(layout.link_ends, dtype=np.int64).reshape(-1, 2)
        joined = (ends >= 0).all(axis=1)
        dist = network_distances(self.n_h, ends[joined, 0], ends[joined, 1], layout.link_length[joined],
                                 sources=place)
        rho_h = gaspari_cohn(dist.T, config.localisation_m)            # (levels, observations)
        first = np.where(ends[:, 0] >= 0, ends[:, 0], ends[:, 1])
        second = np.where(ends[:, 1] >= 0, ends[:, 1], ends[:, 0])
        rho_q = 0.5 * (rho_h[first] + rho_h[second]) if self.n_l else np.zeros((0, place.size))
        self.keys = tuple(model.perturbable_forcing())
        # level boundaries (a tide at the mouth) get additive errors, in the same augmented state
        self.level_keys = tuple(model.perturbable_levels()) if has_capability(model, "perturbable levels") else ()
        self.scale = np.array([config.forcing_error] * len(self.keys) + [config.level_error] * len(self.level_keys))
        entry = np.array([layout.forcing_places[k] for k in (*self.keys, *self.level_keys)], dtype=np.int64)
        # state rows: levels, discharges, then the forcing errors (augmented state), each localised at its place
        self.rho = np.vstack([rho_h, rho_q, rho_h[entry]])
        self.interval = pd.Timedelta(config.interval)
        self.tau_steps = pd.Timedelta(config.forcing_tau) / self.interval

    @property
    def n_forcing(self) -> int:
        """Number of perturbed inflows, laterals and level boundaries (the forcing errors' columns)."""
        return len(self.keys) + len(self.level_keys)

    # -- the ensemble and its errors as stored states ------------------------------------------------

    def initial(self, state: ModelState, rng: np.random.Generator) -> tuple[list[ModelState], np.ndarray]:
        """A cold ensemble: copies of ``state`` and stationary forcing errors."""
        errors = self.scale * rng.standard_normal((self.config.members, self.n_forcing))
        return [state] * self.config.members, errors

    def to_record(self, members: Sequence[ModelState], errors: np.ndarray) -> tuple[pd.Timestamp, int, str, bytes]:
        """The ensemble for the store (:attr:`CycleRecord.ensemble <rivercal.store.CycleRecord>`): one archive."""
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as z:
            z.writestr("state-format.txt", self.model.state_format)
            for m, member in enumerate(members):
                z.writestr(f"members/{m:04d}", self.model.save_state(member))
            array = io.BytesIO()
            np.save(array, np.asarray(errors, dtype=float), allow_pickle=False)
            z.writestr("errors.npy", array.getvalue())
        data = buffer.getvalue()
        self._kept = (data, list(members), np.array(errors, dtype=float))
        return members[0].time, len(members), ENSEMBLE_FORMAT, data

    def from_store(self, store: Store, run: Run, at: pd.Timestamp) -> tuple[list[ModelState], np.ndarray] | None:
        """The ensemble the last cycle stored, if it is at ``at`` and fits (else None: a new ensemble starts).

        When the stored archive is the one this filter wrote last (:meth:`to_record`), its members are taken as
        they are in memory instead of being read back: the same values (a state's archive keeps its arrays
        exactly), without unpacking them.
        """
        stored = store.ensemble(run)
        if stored is None:
            return None
        time, cycle, n, fmt, data = stored
        why = (f"it is at {time}, not {at}" if time != at else f"its format is {fmt!r}" if fmt != ENSEMBLE_FORMAT
               else f"it has {n} members, not {self.config.members}" if n != self.config.members else "")
        members: list[ModelState] = []
        errors = np.zeros(0)
        kept = self._kept
        if not why and kept is not None and kept[0] == data:
            members, errors = list(kept[1]), kept[2].copy()
        elif not why:
            try:
                with zipfile.ZipFile(io.BytesIO(data)) as z:
                    state_format = z.read("state-format.txt").decode("utf-8")
                    errors = np.load(io.BytesIO(z.read("errors.npy")), allow_pickle=False)
                    members = [self.model.load_state(z.read(f"members/{m:04d}"), state_format) for m in range(n)]
            except (zipfile.BadZipFile, KeyError, OSError, ValueError, UnicodeDecodeError) as exc:
                why = f"it cannot be read ({exc})"
        if not why and errors.shape != (self.config.members, self.n_forcing):
            why = f"its forcing errors have shape {errors.shape}"
        if not why and any(m.time != at for m in members):
            why = "its members are not all at its time"
        if why:
            log.warning("the stored ensemble of cycle %d is not used (%s); starting a new ensemble", cycle, why)
            return None
        return members, errors

    # -- filtering and forecasting --------------------------------------------------------------------

    def _factors(self, n_intervals: int, errors: np.ndarray,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Per-member factors (members, intervals, forcing) over ``n_intervals``, and the errors at their end.

        The errors are AR(1) in time, each column with its own σ (:attr:`scale`): log-normal factors of mean one
        on the inflows and laterals, then additive offsets (m) on the level boundaries
        (:class:`~rivercal.models.capabilities.PerturbableLevels`).
        """
        unit = np.divide(errors, self.scale, out=np.zeros_like(errors, dtype=float), where=self.scale > 0)
        e = ar1_series(rng, n_intervals, errors.shape, 1.0, self.tau_steps, initial=unit) * self.scale
        n = len(self.keys)
        factors = np.concatenate([multiplicative_factors(e[..., :n], self.config.forcing_error), e[..., n:]], axis=-1)
        return factors.transpose(1, 0, 2), e[-1]

    def _run(self, parameters: dict[str, float], start: pd.Timestamp, end: pd.Timestamp,
             members: Sequence[ModelState], factors: np.ndarray, output_interval: float) -> MemberRuns:
        """All members from ``start`` to ``end``: in one call of the model, else one run each on the workers."""
        mapper = None
        if not isinstance(self.model, EnsembleRuns):
            if self._tasks is None:
                self._tasks = Tasks(self.model, self.workers)
            tasks = self._tasks
            mapper = lambda fn, items: [f.result() for f in tasks.submit_all(fn, items)]  # noqa: E731
        return run_members(self.model, parameters, start, end, members, factors=factors,
                           interval=self.interval.total_seconds(), output_interval=output_interval,
                           threads=self.config.threads, mapper=mapper, on_failure="report")

    def _survivors(self, result: MemberRuns, errors: np.ndarray,
                   rng: np.random.Generator) -> tuple[list[ModelState], np.ndarray, np.ndarray]:
        """The members' states, forcing errors and values, a failed member replaced by a copy of a surviving one.

        A member whose run fails (a perturbation that made the model diverge) would otherwise stop the cycle;
        the filter goes on with the others, one of them drawn to take its place (its state and its errors).

        Raises
        ------
        ModelRunError
            When every member failed.
        """
        states, values, errors = list(result.states), result.values.copy(), errors.copy()
        if not result.failures:
            return states, errors, values
        alive = [m for m in range(len(states)) if m not in result.failures]
        first = result.failures[min(result.failures)]
        if not alive:
            raise ModelRunError(f"every member of the ensemble failed; the first: {first}")
        log.warning("%d of %d members failed and were replaced by copies of others (the first: %s)",
                    len(result.failures), len(states), first)
        for m in result.failures:
            donor = int(rng.choice(alive))
            states[m], values[m], errors[m] = states[donor], values[donor], errors[donor]
        return states, errors, values

    def close(self) -> None:
        """Stop the worker processes of the members' runs, if any were started."""
        if self._tasks is not None:
            self._tasks.close()
            self._tasks = None

    def assimilate(self, members: list[ModelState], errors: np.ndarray, parameters: dict[str, float],
                   end: pd.Timestamp, observed: pd.DataFrame, rng: np.random.Generator,
                   stage: Callable[[int, int], None] | None = None) -> tuple[list[ModelState], np.ndarray, int]:
        """Advance the members to ``end``, analysing at the end of every interval with the readings inside it.

        ``observed`` is a wide table (UTC index, one column per series of :attr:`series`; NaN: missing) at the
        readings' own time stamps, which need not fall on the analysis times (a sensor every 31 minutes, with
        second offsets). The analysis at the end of the interval (t, t + interval] uses every reading whose
        time lies in it (:meth:`_readings`); the start of the first interval (the members' time) belongs to
        the interval before it, which the previous cycle analysed. Returns the members at ``end``, their forcing
        errors and the number of analyses made. ``stage`` is told the interval about to run and how many there are.
        """
        t = members[0].time
        analyses = 0
        count = math.ceil((end - t) / self.interval)
        analysis = FILTERS[self.config.method]
        observed = observed.reindex(columns=self.series).sort_index()
        done = 0
        while t < end:
            if stage is not None:
                stage(done + 1, count)
            done += 1
            nxt = min(t + self.interval, end)
            factors, errors = self._factors(1, errors, rng)
            result = self._run(parameters, t, nxt, members, factors, self._output_step(nxt - t))
            members, errors, values = self._survivors(result, errors, rng)
            inside = observed[(observed.index > t) & (observed.index <= nxt)]
            t = nxt
            predicted, y, which = self._readings(result.times, values, inside)
            if y.size:
                members, errors = self._analyse(members, errors, predicted, y, analysis, rng, which)
                analyses += 1
        return members, errors, analyses

    def _output_step(self, span: pd.Timedelta) -> float:
        """Output step of the members inside an interval, s: the model's output interval where it divides it.

        The members are interpolated to a reading's time between their outputs either side of it; a model gives
        its series at multiples of its own output interval (SWMM's report step: no finer), so a model whose output
        interval is the analysis interval or does not divide it is interpolated between the interval's ends.
        """
        seconds = span.total_seconds()
        step = float(getattr(self.model, "output_interval", 0.0) or 0.0)
        if 0 < step < seconds and abs(seconds / step - round(seconds / step)) < 1e-9:
            return step
        return seconds

    def _readings(self, times: pd.DatetimeIndex, values: np.ndarray,
                  inside: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The readings of an interval and each member's prediction of them.

        Every finite reading is one observation of the analysis. Its prediction is the member's simulated value
        interpolated linearly in time between the member's outputs either side of the reading's time (the
        members' series over the interval, ``values`` of shape (members, times, observables) at ``times``); the
        analysis at the interval's end then updates the state at that end with its ensemble covariance with
        the predicted readings at their earlier times — the asynchronous EnKF of Sakov, Evensen and Bertino
        (2010, Tellus A 62:24–29), exact for a linear model over the interval. Two readings of one series in an
        interval are two observations with independent errors (σ of the series each).

        Returns
        -------
        tuple
            Predicted readings (readings, members), the readings (readings,; m or m³/s) and the index of each
            reading's series in :attr:`series`.
        """
        if inside.empty:
            return np.zeros((0, values.shape[0])), np.zeros(0), np.zeros(0, dtype=np.int64)
        grid = (times - times[0]).total_seconds().to_numpy()
        at = (inside.index - times[0]).total_seconds().to_numpy()
        y = inside.to_numpy(dtype=float)                                  # (stamps, series)
        rows, which = np.nonzero(np.isfinite(y))
        if rows.size == 0:
            return np.zeros((0, values.shape[0])), np.zeros(0), np.zeros(0, dtype=np.int64)
        i = np.clip(np.searchsorted(grid, at, side="right") - 1, 0, max(grid.size - 2, 0))
        j = np.minimum(i + 1, grid.size - 1)
        width = np.where(grid[j] > grid[i], grid[j] - grid[i], 1.0)
        w = np.clip((at - grid[i]) / width, 0.0, 1.0)                      # weight of the later output
        series = values[:, :, self.columns]                                 # (members, times, series)
        lo, hi = series[:, i[rows], which], series[:, j[rows], which]       # (members, readings)
        predicted = ((1.0 - w[rows]) * lo + w[rows] * hi).T
        return predicted, y[rows, which], which.astype(np.int64)

    def _analyse(self, members: list[ModelState], errors: np.ndarray, predicted: np.ndarray, y: np.ndarray,
                 analysis: Any, rng: np.random.Generator,
                 which: np.ndarray | None = None) -> tuple[list[ModelState], np.ndarray]:
        """Analyse the members with readings ``y`` of the series ``which`` (default: one of each, in order)."""
        which = np.arange(len(self.series)) if which is None else which
        arrays = [self.model.state_arrays(m) for m in members]
        x = np.vstack([np.array([np.concatenate([z, q]) for z, q in arrays]).T, errors.T])
        kwargs = {"rng": rng, "inflation": self.config.inflation, "rho_state": self.rho[:, which]}
        xa = analysis(x, predicted, y, self.sigma[which] ** 2, **kwargs)
        out = [self.model.with_state_arrays(m, xa[: self.n_h, k], xa[self.n_h : self.n_h + self.n_l, k])
               for k, m in enumerate(members)]
        return out, np.ascontiguousarray(xa[self.n_h + self.n_l :].T)

    def expected_factors(self, errors: np.ndarray, n_intervals: int) -> np.ndarray:
        """The forcing the members are expected to have over ``n_intervals``: (intervals, forcing).

        A member's error continues as AR(1) from its value now, e₀: in interval k its expected value is φᵏ e₀,
        with variance σ²(1 − φ²ᵏ) around it, so its factor exp(e − σ²/2) has the expectation
        exp(φᵏ e₀ − σ² φ²ᵏ / 2) (a log-normal's mean) and a level offset φᵏ e₀; averaged over the members. Far
        ahead every factor tends to one and every offset to zero: the forcing the model was given.
        """
        phi = math.exp(-1.0 / self.tau_steps)
        k = np.arange(1, n_intervals + 1, dtype=float)[:, None, None]
        e0 = np.asarray(errors, dtype=float)[None]                    # (1, members, forcing)
        n = len(self.keys)
        sigma = self.scale[None, None, :n]
        factors = np.exp(phi**k * e0[..., :n] - 0.5 * sigma**2 * phi ** (2 * k)).mean(axis=1)
        offsets = (phi**k * e0[..., n:]).mean(axis=1)
        return np.concatenate([factors, offsets], axis=-1)

    def forecast(self, members: list[ModelState], errors: np.ndarray, parameters: dict[str, float],
                 horizon: pd.Timedelta, output_interval: float, rng: np.random.Generator) -> EnsembleForecast:
        """Forecast ``horizon`` from the members: the issued forecast and the 90 % band (observation error included).

        The issued forecast is the members' mean, or with ``issued = "central"`` one more run, in the same call,
        from the members' mean levels and discharges (the rest of its state, e.g. its controllers', that of the
        first member) with :meth:`expected_factors`; should that run fail, the members' mean, with a warning.
        """
        t0 = members[0].time
        n_int = int(np.ceil(horizon / self.interval))
        factors, _ = self._factors(n_int, errors, rng)
        n = len(members)
        central = self.config.issued == "central"
        if central:
            arrays = [self.model.state_arrays(m) for m in members]
            mean_state = self.model.with_state_arrays(members[0], np.mean([a[0] for a in arrays], axis=0),
                                                      np.mean([a[1] for a in arrays], axis=0))
            members = [*members, mean_state]
            factors = np.concatenate([factors, self.expected_factors(errors, n_int)[None]], axis=0)
        result = self._run(parameters, t0, t0 + horizon, members, factors, output_interval)
        alive = [m for m in range(n) if m not in result.failures]
        if not alive:
            raise ModelRunError(f"every member's forecast failed; the first: {result.failures[min(result.failures)]}")
        failed = [m for m in result.failures if m < n]
        if failed:
            log.warning("%d of %d members' forecasts failed and are left out of the forecast (the first: %s)",
                        len(failed), n, result.failures[min(failed)])
        values = result.values[alive][:, :, self.columns]                # (N, T, m)
        noisy = values[None] + self.sigma * rng.standard_normal((max(1, 2048 // n), *values.shape))
        flat = noisy.reshape(-1, *values.shape[1:])
        frame = lambda v: pd.DataFrame(v, index=result.times, columns=self.series)  # noqa: E731
        low, high = np.quantile(flat, [0.05, 0.95], axis=0)  # one partition for both: the same values as apart
        issued = values.mean(axis=0)
        if central and n in result.failures:
            log.warning("the central forecast run failed (%s); the members' mean is issued", result.failures[n])
        elif central:
            issued = result.values[n][:, self.columns]
        return EnsembleForecast(mean=frame(issued), low=frame(low), high=frame(high))


def assimilation_cycle(service: OnlineService, spec: CycleSpec, run_start: pd.Timestamp, state: ModelState,
                       accepted: dict[str, float]) -> tuple[EnsembleForecast, tuple, int]:
    """The state updating of one cycle of the on-line service (module docstring).

    Returns the forecast of the analysed ensemble, the ensemble to store (the members at t₀ and their
    forcing errors, :meth:`EnsembleFilter.to_record`) and the number of analyses.
    """
    filt = service.filter
    assert filt is not None
    t0 = spec.issue_time
    rng = np.random.default_rng([filt.config.seed, spec.cycle])
    parameters = service._quantities(accepted) if filt.config.mode == "both" else dict(service.config.dss)
    stored = filt.from_store(service.store, service.run, t0 - service.period)
    if stored is None:
        log.info("cycle %d: a new ensemble of %d members from the state at %s", spec.cycle, filt.config.members,
                 run_start)
        members, errors = filt.initial(state, rng)
    else:
        members, errors = stored
    observed = service.store.observation_table(filt.series, members[0].time, t0, sources=service.config.sources)
    wide = observed.pivot_table(index="time", columns="series", values="value").reindex(columns=filt.series)
    def stage(k: int, n: int) -> None:
        service._stage(f"cycle {spec.cycle} {t0:%Y-%m-%d %H:%M}: {filt.config.members} members, interval {k}/{n}")

    members, errors, analyses = filt.assimilate(members, errors, parameters, t0, wide, rng, stage=stage)
    service._stage(f"cycle {spec.cycle} {t0:%Y-%m-%d %H:%M}: {filt.config.members} members' forecasts")
    fc = filt.forecast(members, errors, parameters, service.horizon, service.config.output_interval_s, rng)
    return fc, filt.to_record(members, errors), analyses
