"""Model error for an ensemble: AR(1) perturbations of inflows and laterals in time.

Rain and runoff errors persist for hours: a shower that the radar missed keeps the laterals too low
for the whole event. White noise per time step would average out within an hour of model time; a
first-order autoregressive process with correlation time τ does not (Evensen 2003, Ocean Dyn.
53:343–367, §4.2, "red" model noise):

    eₖ₊₁ = φ eₖ + √(1 − φ²) σ ηₖ,  φ = exp(−Δt/τ),  ηₖ ~ N(0, 1),

stationary with standard deviation σ. Discharges are multiplied by the log-normal factor
exp(e − σ²/2), whose mean is one and which never turns an inflow into an extraction.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ar1_series", "multiplicative_factors"]


def ar1_series(rng: np.random.Generator, n_steps: int, shape: tuple[int, ...], sigma: float, tau_steps: float,
               initial: np.ndarray | None = None) -> np.ndarray:
    """AR(1) series in time: an array of shape ``(n_steps, *shape)``, stationary with standard deviation ``sigma``.

    Parameters
    ----------
    rng
        The random source.
    n_steps
        Number of steps.
    shape
        Shape of each step's values (e.g. (members, series)).
    sigma
        Stationary standard deviation (unit of the perturbed quantity; dimensionless for factors).
    tau_steps
        Correlation time τ, in steps (> 0); ``inf`` gives a constant per series.
    initial
        The value before the first step (default: a draw from the stationary distribution), so that a
        series can be continued across windows.
    """
    if not sigma >= 0 or not tau_steps > 0:
        raise ValueError(f"AR(1) needs sigma >= 0 and a positive correlation time, got {sigma}, {tau_steps}")
    phi = float(np.exp(-1.0 / tau_steps))
    innov = np.sqrt(1.0 - phi * phi) * sigma
    e = sigma * rng.standard_normal(shape) if initial is None else np.asarray(initial, dtype=float).copy()
    out = np.empty((n_steps, *shape))
    for k in range(n_steps):
        e = phi * e + innov * rng.standard_normal(shape)
        out[k] = e
    return out


def multiplicative_factors(errors: np.ndarray, sigma: float) -> np.ndarray:
    """Log-normal factors exp(e − σ²/2) of mean one for AR(1) errors ``e`` of standard deviation ``sigma``."""
    return np.exp(np.asarray(errors, dtype=float) - 0.5 * sigma * sigma)
