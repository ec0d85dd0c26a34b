"""Noise models for twin observations (seeded, reproducible).

- ``none``: the observations are the truth.
- ``white``: uniform in ±2.5 cm for levels and ±0.1 m³/s for discharges, independent per value
  (thesis §4-2-3: "uniform distributed in a prescribed interval").
- ``gaussian``: normal with standard deviation 2.5 cm for levels and 0.1 m³/s for discharges.
- ``pink``: 1/f noise (thesis §6-3 recommends coloured noise): a spectrum with power ∝ 1/f, scaled to
  the same standard deviation as ``gaussian``; consecutive hours are correlated, as real gauge drift is.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LEVEL_AMPLITUDE", "NOISE_MODELS", "Q_AMPLITUDE", "add_noise"]

#: Noise amplitude for levels, m, and for discharges, m³/s (thesis §4-2-3).
LEVEL_AMPLITUDE = 0.025
Q_AMPLITUDE = 0.1
NOISE_MODELS = ("none", "white", "gaussian", "pink")


def _pink(rng: np.random.Generator, n: int) -> np.ndarray:
    """Unit-variance 1/f noise of length n (spectral shaping of white Gaussian noise)."""
    if n < 2:
        return rng.standard_normal(n)
    spectrum = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n)
    f[0] = f[1]
    spectrum /= np.sqrt(f)
    x = np.fft.irfft(spectrum, n)
    x -= x.mean()
    return x / x.std()


def add_noise(values: np.ndarray, quantity: str, model: str, rng: np.random.Generator) -> np.ndarray:
    """``values`` plus noise of ``model`` for a quantity (``h``, ``h_up``, ``h_down`` in m; ``Q`` in m³/s).

    Raises
    ------
    ValueError
        For an unknown noise model.
    """
    if model not in NOISE_MODELS:
        raise ValueError(f"unknown noise model {model!r}; choose one of {', '.join(NOISE_MODELS)}")
    amplitude = Q_AMPLITUDE if quantity == "Q" else LEVEL_AMPLITUDE
    n = values.size
    if model == "none":
        return values.copy()
    if model == "white":
        return values + rng.uniform(-amplitude, amplitude, n)
    if model == "gaussian":
        return values + amplitude * rng.standard_normal(n)
    return values + amplitude * _pink(rng, n)
