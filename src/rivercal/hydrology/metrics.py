"""Goodness-of-fit measures for discharge series (pairs with a missing value are dropped)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["kling_gupta", "nash_sutcliffe"]


def _pairs(observed: ArrayLike, simulated: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    obs = np.asarray(observed, dtype=float).ravel()
    sim = np.asarray(simulated, dtype=float).ravel()
    if obs.shape != sim.shape:
        raise ValueError(f"observed and simulated differ in length ({obs.size} vs {sim.size})")
    ok = np.isfinite(obs) & np.isfinite(sim)
    if ok.sum() < 2:
        raise ValueError("fewer than two pairs of finite values")
    return obs[ok], sim[ok]


def nash_sutcliffe(observed: ArrayLike, simulated: ArrayLike) -> float:
    """Nash-Sutcliffe efficiency (-): 1 - Σ(sim - obs)² / Σ(obs - mean(obs))²; 1 is perfect."""
    obs, sim = _pairs(observed, simulated)
    return float(1.0 - np.sum((sim - obs) ** 2) / np.sum((obs - obs.mean()) ** 2))


def kling_gupta(observed: ArrayLike, simulated: ArrayLike) -> float:
    """Kling-Gupta efficiency (-) of Gupta et al. (2009): 1 - sqrt((r-1)² + (α-1)² + (β-1)²).

    ``r`` is the linear correlation, ``α = σ_sim / σ_obs`` and ``β = μ_sim / μ_obs``; 1 is perfect.
    Gupta, H. V., Kling, H., Yilmaz, K. K., Martinez, G. F. (2009), J. Hydrol. 377, 80-91.
    """
    obs, sim = _pairs(observed, simulated)
    r = float(np.corrcoef(obs, sim)[0, 1])
    alpha = float(sim.std() / obs.std())
    beta = float(sim.mean() / obs.mean())
    return float(1.0 - np.sqrt((r - 1.0) ** 2 + (alpha - 1.0) ** 2 + (beta - 1.0) ** 2))
