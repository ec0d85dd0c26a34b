"""State updating for the on-line service: an ensemble Kalman filter over the embedded engine.

Modes (``--assimilate``): ``parameters`` — the daily parameter cycle alone (no ensemble); ``states`` —
the ensemble filter alone, with the model's (the DSS's) parameters; ``both`` — the daily parameter
cycle, and between cycles hourly state analyses with the parameters it accepted.

Each cycle issued at t₀ takes the members the previous cycle left at t₀ − period (hot start of all
members; a cold ensemble — copies of the updated model's state at the start of the window — for the
first cycle or when none is stored), and then per analysis interval

1. advances all members in one batched engine call (:func:`rivercal.engine.ensemble.run_ensemble`), each
   with its own inflows and laterals: the model's forcing times log-normal AR(1) factors
   (:mod:`rivercal.assimilate.perturb`; the model error — rain and runoff that were wrong);
2. analyses the levels and discharges of every calculation point, and the members' forcing errors
   (an augmented state: an error of the rain persists for hours, so the forecast gains from knowing it),
   with the observations at that time (:mod:`rivercal.assimilate.filters`; localised along the network
   with the Gaspari–Cohn taper, a forcing error at the point where it enters), and writes them back into
   the members' states (volumes from the analysed levels, velocities scaled with the analysed discharges).

From t₀ the members forecast the horizon with their forcing perturbed on; the forecast is the ensemble
mean, its 90 % band the 5 % and 95 % quantiles of the members' values plus the observation error (the
band is for the observations, which carry that error).
"""

from __future__ import annotations

import io
import logging
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal.assimilate import FILTERS, gaspari_cohn, network_distances
from rivercal.assimilate.perturb import ar1_series, multiplicative_factors
from rivercal.engine.ensemble import run_ensemble
from rivercal.engine.kernels.batch import volumes
from rivercal.engine.kernels.codes import BOUNDARY_DISCHARGE, OBS_LEVEL
from rivercal.engine.state import EngineState
from rivercal.observations import DEFAULT_SIGMA

__all__ = ["ASSIMILATE_MODES", "AssimilationConfig", "EnsembleFilter", "EnsembleForecast", "assimilation_cycle"]

log = logging.getLogger(__name__)

#: The modes of the on-line service (module docstring).
ASSIMILATE_MODES = ("parameters", "states", "both")
#: Format tag of a stored ensemble: an ``.npz`` archive (no pickle) of the members' state arrays stacked on a
#: first axis (``z``, ``dz``, ``vol``, ``u``, ``q``, ``pump_on``, ``ctl``), their ``signature`` and time (``time_ns``),
#: and the members' AR(1) forcing errors (``errors``).
ENSEMBLE_FORMAT = "rivercal-ensemble-npz-1"
_STATE_ARRAYS = ("z", "dz", "vol", "u", "q", "pump_on", "ctl")


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
        Correlation time of the forcing errors.
    seed
        Seed of the perturbations (per cycle, the seed and the cycle number).
    threads
        Threads of the batched engine (None: all).
    """

    mode: Literal["parameters", "states", "both"] = "parameters"
    members: int = 64
    method: Literal["etkf", "enkf"] = "etkf"
    interval: str = "1h"
    inflation: float = 1.0
    localisation_m: float = 20_000.0
    forcing_error: float = 0.3
    forcing_tau: str = "24h"
    seed: int = 0
    threads: int | None = None

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

    def stored(self) -> dict[str, Any]:
        """The configuration as stored with the run (the thread count is not part of it)."""
        out = asdict(self)
        out.pop("threads")
        return out


@dataclass(frozen=True)
class EnsembleForecast:
    """The forecast of an analysed ensemble: mean and 90 % band per series (m AD or m³/s), UTC index."""

    mean: pd.DataFrame
    low: pd.DataFrame
    high: pd.DataFrame


class EnsembleFilter:
    """The ensemble filter of one run (module docstring).

    Parameters
    ----------
    model
        The embedded model (a :class:`~rivercal.engine.Simulator`).
    config
        The filter configuration.
    series
        Observed series the filter uses.
    sigma
        σ per quantity or series id (default :data:`~rivercal.observations.DEFAULT_SIGMA`), m or m³/s.
    """

    def __init__(self, model: Any, config: AssimilationConfig, series: list[str],
                 sigma: dict[str, float] | None = None):
        if not hasattr(model, "compiled"):
            raise ValueError(f"state updating needs the embedded engine; model {model.name!r} is another kind")
        self.model = model
        self.config = config
        self.series = list(series)
        c = model.compiled
        a = c.arrays
        self.n_h, self.n_l = c.n_hpoints, c.n_links
        col = {name: i for i, name in enumerate(c.observables)}
        self.columns = np.array([col[s] for s in self.series], dtype=np.int64)
        sig = dict(DEFAULT_SIGMA if sigma is None else sigma)
        self.sigma = np.array([float(sig.get(s, sig.get(s.rpartition(".")[2]))) for s in self.series])
        # each observation's place: its h-point (a level) or the upstream point of its link (a discharge)
        place = np.where(a.ob_type[self.columns] == OBS_LEVEL, a.ob_i1[self.columns], a.lk_k1[a.ob_i1[self.columns]])
        dist = network_distances(self.n_h, a.lk_k1, a.lk_k2, np.maximum(a.lk_len, 1.0), sources=place)
        rho_h = gaspari_cohn(dist.T, config.localisation_m)
        self.perturbed = np.array([k.startswith("lateral:") for k in c.forcing_keys])
        where = np.zeros(len(c.forcing_keys), dtype=np.int64)   # the point each forcing column enters at
        where[a.lat_col] = a.lat_hp
        for bnd in range(a.b_hp.size):
            where[a.b_col[bnd]] = a.b_hp[bnd]
            if a.b_type[bnd] == BOUNDARY_DISCHARGE:
                self.perturbed[a.b_col[bnd]] = True
        # state rows: levels, discharges, then the forcing errors (augmented state), each localised at its place
        self.rho = np.vstack([rho_h, 0.5 * (rho_h[a.lk_k1] + rho_h[a.lk_k2]), rho_h[where[self.perturbed]]])
        self.interval = pd.Timedelta(config.interval)
        self.tau_steps = pd.Timedelta(config.forcing_tau) / self.interval

    # -- the ensemble and its errors as stored states ------------------------------------------------

    def initial(self, state: EngineState, rng: np.random.Generator) -> tuple[list[EngineState], np.ndarray]:
        """A cold ensemble: copies of ``state`` and stationary forcing errors."""
        errors = self.config.forcing_error * rng.standard_normal((self.config.members, int(self.perturbed.sum())))
        return [state.copy() for _ in range(self.config.members)], errors

    def to_record(self, members: list[EngineState], errors: np.ndarray) -> tuple[pd.Timestamp, int, str, bytes]:
        """The ensemble for the store (:attr:`CycleRecord.ensemble <rivercal.store.CycleRecord>`): one archive."""
        buffer = io.BytesIO()
        np.savez(buffer, time_ns=np.int64(members[0].time.value), signature=np.asarray(members[0].signature),
                 errors=errors, **{k: np.stack([getattr(m, k) for m in members]) for k in _STATE_ARRAYS})
        return members[0].time, len(members), ENSEMBLE_FORMAT, buffer.getvalue()

    def from_store(self, store: Any, run: Any, at: pd.Timestamp) -> tuple[list[EngineState], np.ndarray] | None:
        """The ensemble the last cycle stored, if it is at ``at`` and fits (else None: a new ensemble starts)."""
        stored = store.ensemble(run)
        if stored is None:
            return None
        time, cycle, n, fmt, data = stored
        why = (f"it is at {time}, not {at}" if time != at else f"its format is {fmt!r}" if fmt != ENSEMBLE_FORMAT
               else f"it has {n} members, not {self.config.members}" if n != self.config.members else "")
        if not why:
            try:
                with np.load(io.BytesIO(data), allow_pickle=False) as f:
                    arrays = {k: f[k] for k in (*_STATE_ARRAYS, "errors", "signature")}
            except (OSError, KeyError, ValueError) as exc:
                why = f"it cannot be read ({exc})"
        if not why:
            signature = tuple(int(v) for v in arrays["signature"])
            errors = arrays["errors"]
            if signature != (self.n_h, self.n_l):
                why = "it belongs to another network"
            elif errors.shape != (self.config.members, int(self.perturbed.sum())):
                why = f"its forcing errors have shape {errors.shape}"
        if why:
            log.warning("the stored ensemble of cycle %d is not used (%s); starting a new ensemble", cycle, why)
            return None
        members = [EngineState(time=time, signature=signature, **{k: arrays[k][m].copy() for k in _STATE_ARRAYS})
                   for m in range(n)]
        return members, errors

    # -- filtering and forecasting --------------------------------------------------------------------

    def _forcing(self, start: pd.Timestamp, n_intervals: int, errors: np.ndarray, rng: np.random.Generator):
        """Per-member forcing over ``n_intervals`` analysis intervals, and the errors at their end."""
        steps_per = round(self.interval.total_seconds() / self.model.dt)
        base = self.model.forcing_matrix(start, n_intervals * steps_per)
        e = ar1_series(rng, n_intervals, errors.shape, self.config.forcing_error, self.tau_steps, initial=errors)
        factors = np.repeat(multiplicative_factors(e, self.config.forcing_error), steps_per, axis=0)  # (steps, N, k)
        forcing = np.repeat(base[None], self.config.members, axis=0)
        forcing[:, :, self.perturbed] *= factors.transpose(1, 0, 2)
        return forcing, e[-1]

    def assimilate(self, members: list[EngineState], errors: np.ndarray, parameters: dict[str, float],
                   end: pd.Timestamp, observed: pd.DataFrame, rng: np.random.Generator):
        """Advance the members to ``end``, analysing at every interval.

        ``observed`` is a wide table (UTC index, one column per series of :attr:`series`; NaN: missing).
        Returns the members at ``end``, their forcing errors and the number of analyses made.
        """
        t = members[0].time
        analyses = 0
        analysis = FILTERS[self.config.method]
        while t < end:
            nxt = min(t + self.interval, end)
            forcing, errors = self._forcing(t, 1, errors, rng)
            forcing = forcing[:, : round((nxt - t).total_seconds() / self.model.dt)]
            result = run_ensemble(self.model, [parameters] * len(members), t, nxt, members, forcing=forcing,
                                  output_interval=(nxt - t).total_seconds(), n_threads=self.config.threads,
                                  on_failure="raise")
            members = list(result.states)
            t = nxt
            if t in observed.index:
                y = observed.loc[t, self.series].to_numpy(dtype=float)
                if np.isfinite(y).any():
                    predicted = result.values[:, -1, self.columns].T
                    members, errors = self._analyse(members, errors, predicted, y, analysis, rng)
                    analyses += 1
        return members, errors, analyses

    def _analyse(self, members, errors, predicted, y, analysis, rng):
        x = np.vstack([np.array([np.concatenate([m.z, m.q]) for m in members]).T, errors.T])
        kwargs = {"rng": rng, "inflation": self.config.inflation, "rho_state": self.rho}
        xa = analysis(x, predicted, y, self.sigma**2, **kwargs)
        a = self.model.compiled.arrays
        out = []
        for k, m in enumerate(members):
            s = m.copy()
            z = np.maximum(xa[: self.n_h, k], a.hp_bed)   # never below the bed
            q = xa[self.n_h : self.n_h + self.n_l, k]
            s.z = z
            s.vol = np.empty_like(z)
            volumes(a, z, s.vol)
            with np.errstate(divide="ignore", invalid="ignore"):
                area = np.where(np.abs(m.u) > 1e-9, m.q / m.u, np.nan)
            s.u = np.where(np.isfinite(area) & (area > 0), q / area, m.u)
            s.q = np.where(np.isfinite(area) & (area > 0), q, m.q)
            out.append(s)
        return out, np.ascontiguousarray(xa[self.n_h + self.n_l :].T)

    def forecast(self, members: list[EngineState], errors: np.ndarray, parameters: dict[str, float],
                 horizon: pd.Timedelta, output_interval: float, rng: np.random.Generator) -> EnsembleForecast:
        """Forecast ``horizon`` from the members: mean and 90 % band (observation error included)."""
        t0 = members[0].time
        n_int = int(np.ceil(horizon / self.interval))
        forcing, _ = self._forcing(t0, n_int, errors, rng)
        forcing = forcing[:, : round(horizon.total_seconds() / self.model.dt)]
        result = run_ensemble(self.model, [parameters] * len(members), t0, t0 + horizon, members, forcing=forcing,
                              output_interval=output_interval, n_threads=self.config.threads, on_failure="raise")
        values = result.values[:, :, self.columns]                       # (N, T, m)
        noisy = values[None] + self.sigma * rng.standard_normal((max(1, 2048 // len(members)), *values.shape))
        flat = noisy.reshape(-1, *values.shape[1:])
        frame = lambda v: pd.DataFrame(v, index=result.times, columns=self.series)  # noqa: E731
        return EnsembleForecast(mean=frame(values.mean(axis=0)), low=frame(np.quantile(flat, 0.05, axis=0)),
                                high=frame(np.quantile(flat, 0.95, axis=0)))


def assimilation_cycle(service: Any, spec: Any, run_start: pd.Timestamp, state: Any,
                       accepted: dict[str, float]) -> tuple[EnsembleForecast, tuple, int]:
    """The state updating of one cycle of the on-line service (module docstring).

    Returns the forecast of the analysed ensemble, the ensemble to store (the members at t₀ and their
    forcing errors, :meth:`EnsembleFilter.to_record`) and the number of analyses.
    """
    filt: EnsembleFilter = service.filter
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
    members, errors, analyses = filt.assimilate(members, errors, parameters, t0, wide, rng)
    fc = filt.forecast(members, errors, parameters, service.horizon, service.config.output_interval_s, rng)
    return fc, filt.to_record(members, errors), analyses


#: Lead-time buckets of :func:`mae_by_lead`, h: (0, 6] with lead 0 included, (6, 12], (12, 24], (24, 48].
MAE_BUCKETS_H = ((0, 6), (6, 12), (12, 24), (24, 48))


def mae_by_lead(store: Any, run: Any, series: list[str], truth: pd.DataFrame | None = None) -> dict[str, Any]:
    """Mean absolute error (m) of the stored level forecasts per kind and lead bucket.

    Against ``truth`` (a twin's noise-free series: wide, UTC index) when given, else against the stored
    observations (whose error then adds to the forecast's).
    """
    levels = [s for s in series if s.rpartition(".")[2] in ("h", "h_up", "h_down")]
    fc = store.forecasts(run)
    fc = fc[fc["series"].isin(levels)]
    out: dict[str, Any] = {"against": "observations" if truth is None else "truth"}
    if fc.empty:
        return out
    if truth is None:
        reference = store.observation_table(levels, fc["time"].min(), fc["time"].max(), sources=None)
    else:
        long = truth[[c for c in levels if c in truth.columns]].rename_axis("time").reset_index()
        reference = long.melt(id_vars="time", var_name="series", value_name="value")
    pairs = fc.merge(reference[["series", "time", "value"]], on=["series", "time"], suffixes=("", "_obs"))
    for kind, part in pairs.groupby("kind"):
        err = (part["value"] - part["value_obs"]).abs()
        out[str(kind)] = {}
        for lo, hi in MAE_BUCKETS_H:
            lead = part["lead_h"]
            inside = ((lead > lo) | ((lead == lo) & (lo == 0))) & (lead <= hi)
            out[str(kind)][f"{lo}-{hi}h"] = float(err[inside].mean()) if inside.any() else None
    return out


def band_coverage(store: Any, run: Any, *, sources: list[str] | None = None) -> dict[str, Any]:
    """Share of the stored level observations inside the run's stored forecast bands, lead > 0.

    ``n`` is the number of (band, observation) pairs; ``sources`` as for the store's observation table.
    """
    bands = store.forecast_bands(run)
    if len(bands):
        bands = bands[bands["series"].str.rpartition(".")[2].isin(("h", "h_up", "h_down")) & (bands["lead_h"] > 0)]
    if bands.empty:
        return {"n": 0, "fraction": None}
    obs = store.observation_table(sorted(bands["series"].unique()), bands["time"].min(), bands["time"].max(),
                                  sources=sources)
    pairs = bands.merge(obs[["series", "time", "value"]], on=["series", "time"])
    inside = (pairs["value"] >= pairs["low"]) & (pairs["value"] <= pairs["high"])
    return {"n": len(pairs), "fraction": float(inside.mean()) if len(pairs) else None,
            "probability": float(bands["probability"].iloc[0])}
