"""NIST StRD nonlinear least-squares problems (certified values) for the optimiser tests and benchmark.

The data files are in ``tests/data/nist`` (public domain, see the README there). The model formulas are
written from the headers of those files. ``problem(name, start)`` returns the residual function
r(b) = y − f(x; b) (Nelson: log y − f), the NIST start vector, the certified values and wide bounds.

Outside the region NIST's start values lead to, some models overflow (exp of a large argument) or divide
by zero; the residual functions clip exponents and replace non-finite model values by ±1e50 so that a
global method sampling the wide box sees a very bad but finite cost (the "penalty" policy).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[1] / "data" / "nist"

LOWER = ("Misra1a", "Chwirut1", "Chwirut2", "Lanczos3", "Gauss1", "Gauss2", "DanWood", "Misra1b")
AVERAGE = ("Kirby2", "Hahn1", "Nelson", "MGH17", "Lanczos1", "Lanczos2", "Gauss3", "Misra1c", "Misra1d",
           "Roszman1", "ENSO")


def _exp(z: np.ndarray) -> np.ndarray:
    return np.exp(np.minimum(z, 300.0))


def _misra1a(b, x):
    return b[0] * (1 - _exp(-b[1] * x))


def _chwirut(b, x):
    return _exp(-b[0] * x) / (b[1] + b[2] * x)


def _three_exp(b, x):
    return b[0] * _exp(-b[1] * x) + b[2] * _exp(-b[3] * x) + b[4] * _exp(-b[5] * x)


def _gauss(b, x):
    return (b[0] * _exp(-b[1] * x) + b[2] * _exp(-((x - b[3]) ** 2) / b[4] ** 2)
            + b[5] * _exp(-((x - b[6]) ** 2) / b[7] ** 2))


def _danwood(b, x):
    return b[0] * x ** b[1]


def _misra1b(b, x):
    return b[0] * (1 - (1 + b[1] * x / 2) ** (-2))


def _kirby2(b, x):
    return (b[0] + b[1] * x + b[2] * x**2) / (1 + b[3] * x + b[4] * x**2)


def _hahn1(b, x):
    return (b[0] + b[1] * x + b[2] * x**2 + b[3] * x**3) / (1 + b[4] * x + b[5] * x**2 + b[6] * x**3)


def _nelson(b, x):
    return b[0] - b[1] * x[:, 0] * _exp(-b[2] * x[:, 1])


def _mgh17(b, x):
    return b[0] + b[1] * _exp(-x * b[3]) + b[2] * _exp(-x * b[4])


def _misra1c(b, x):
    return b[0] * (1 - (1 + 2 * b[1] * x) ** (-0.5))


def _misra1d(b, x):
    return b[0] * b[1] * x / (1 + b[1] * x)


def _roszman1(b, x):
    return b[0] - b[1] * x - np.arctan(b[2] / (x - b[3])) / math.pi


def _enso(b, x):
    w = 2 * math.pi * x
    return (b[0] + b[1] * np.cos(w / 12) + b[2] * np.sin(w / 12) + b[4] * np.cos(w / b[3])
            + b[5] * np.sin(w / b[3]) + b[7] * np.cos(w / b[6]) + b[8] * np.sin(w / b[6]))


MODELS: dict[str, Callable] = {
    "Misra1a": _misra1a, "Chwirut1": _chwirut, "Chwirut2": _chwirut, "Lanczos1": _three_exp,
    "Lanczos2": _three_exp, "Lanczos3": _three_exp, "Gauss1": _gauss, "Gauss2": _gauss, "Gauss3": _gauss,
    "DanWood": _danwood, "Misra1b": _misra1b, "Kirby2": _kirby2, "Hahn1": _hahn1, "Nelson": _nelson,
    "MGH17": _mgh17, "Misra1c": _misra1c, "Misra1d": _misra1d, "Roszman1": _roszman1, "ENSO": _enso,
}


def _sorted_groups(b: np.ndarray, groups: list[list[int]], key: int, reverse: bool = False) -> np.ndarray:
    """Reorder interchangeable parameter groups (the terms of a sum) by the value at position ``key``."""
    out = b.copy()
    blocks = sorted((b[g] for g in groups), key=lambda v: v[key], reverse=reverse)
    for g, values in zip(groups, blocks, strict=True):
        out[g] = values
    return out


def canonical(name: str, b: np.ndarray) -> np.ndarray:
    """The representative of b among the parameter vectors that define the same model.

    Sums of exponentials, Gaussians or harmonics do not change when their terms are permuted, a Gaussian
    width enters squared, and a harmonic with period −P equals one with period P and a sine coefficient of
    the other sign. A global method may land on any of these equivalent optima; the certified values are
    one of them (terms ordered as NIST orders them).
    """
    b = np.array(b, dtype=float)
    if name.startswith("Lanczos"):
        return _sorted_groups(b, [[0, 1], [2, 3], [4, 5]], key=1)
    if name.startswith("Gauss"):
        b[[4, 7]] = np.abs(b[[4, 7]])
        return _sorted_groups(b, [[2, 3, 4], [5, 6, 7]], key=1)
    if name == "MGH17":
        return _sorted_groups(b, [[1, 3], [2, 4]], key=1)
    if name == "ENSO":
        for period, sine in ((3, 5), (6, 8)):
            if b[period] < 0:
                b[period], b[sine] = -b[period], -b[sine]
        return _sorted_groups(b, [[3, 4, 5], [6, 7, 8]], key=0, reverse=True)
    return b


@dataclass(frozen=True)
class Problem:
    """One NIST problem from one of its two starting points."""

    name: str
    start: int
    x0: np.ndarray
    certified: np.ndarray
    certified_ssr: float
    lb: np.ndarray
    ub: np.ndarray
    x: np.ndarray
    y: np.ndarray

    def residuals(self, b: np.ndarray) -> np.ndarray:
        """r(b) = y − f(x; b), finite everywhere."""
        with np.errstate(all="ignore"):
            f = MODELS[self.name](b, self.x)
            r = (np.log(self.y) if self.name == "Nelson" else self.y) - f
        if not np.all(np.isfinite(r)):
            r = np.nan_to_num(r, nan=1e50, posinf=1e50, neginf=-1e50)
        return r

    def digits(self, b: np.ndarray) -> float:
        """Significant digits reached: min over parameters of −log10(|b − c|/|c|), capped at 11.

        b is first mapped to its :func:`canonical` representative (permuted terms count as the same fit).
        """
        rel = np.abs(canonical(self.name, b) - self.certified) / np.abs(self.certified)
        with np.errstate(divide="ignore"):
            lre = -np.log10(rel)
        return float(min(11.0, np.min(lre)))


def _read(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    lines = (DATA / f"{name}.dat").read_text(encoding="ascii").splitlines()
    header = "\n".join(lines[:60])
    first, last = map(int, re.search(r"Data\s+\(lines\s+(\d+)\s+to\s+(\d+)\)", header).groups())
    rows = []
    for line in lines[:60]:
        match = re.match(r"\s*b\d+\s*=\s*(\S+)\s+(\S+)\s+(\S+)\s+(\S+)", line)
        if match:
            rows.append([float(v) for v in match.groups()])
    params = np.array(rows)
    ssr = float(re.search(r"Residual Sum of Squares:\s+(\S+)", header).group(1))
    data = np.array([[float(v) for v in line.split()] for line in lines[first - 1:last]])
    x = data[:, 1:] if data.shape[1] > 2 else data[:, 1]
    return params[:, 0], params[:, 1], params[:, 2], ssr, x, data[:, 0]


def problem(name: str, start: int = 1) -> Problem:
    """The NIST problem ``name`` from start 1 or 2, with wide bounds.

    The bounds are certified − w … certified + 2w with w = 100·|certified| + 10: wide enough not to help a
    local method, and not centred on the answer (a symmetric box would hand a grid or a sampler the
    certified value as the box centre).
    """
    start1, start2, certified, ssr, x, y = _read(name)
    width = 100.0 * np.abs(certified) + 10.0
    x0 = start1 if start == 1 else start2
    return Problem(name, start, x0, certified, ssr, certified - width, certified + 2 * width, x, y)


def search_box(p: Problem) -> tuple[np.ndarray, np.ndarray]:
    """x0 ± |x0| inside the bounds: where samplers start (SCE-UA's initial population, grid, GLUE)."""
    return np.maximum(p.lb, p.x0 - np.abs(p.x0)), np.minimum(p.ub, p.x0 + np.abs(p.x0))


def settings(method: str, p: Problem) -> dict:
    """Keyword arguments with which the tests and the benchmark run ``method`` on ``p``.

    Local methods start from the NIST start vector with perturbations (DuD) of 1 % of it and tight
    tolerances; SCE-UA draws its initial population in x0 ± |x0| but searches the whole wide box; grid
    and GLUE (which cannot use a start point) sample x0 ± |x0| instead of the wide box, with 20 000 points.
    """
    step = 0.01 * np.where(p.x0 != 0, np.abs(p.x0), 1.0)
    low, high = search_box(p)
    n = p.x0.size
    table = {
        "dud": {"options": {"abs_tol": 0.0, "rel_tol": 1e-13, "rel_tol_linear": 0.0, "negligible_cost": 0.0,
                            "max_outer": 1000, "initial_step": step}},
        "trf": {"options": {"ftol": 1e-15, "xtol": 1e-15, "gtol": 1e-15}},
        "sce_ua": {"options": {"seed": 1, "peps": 1e-10, "pcento": 0.0, "kstop": 10, "init_lb": low,
                               "init_ub": high}, "max_nfev": 200_000},
        "dds": {"options": {"seed": 1, "max_evaluations": 20_000}},
        "nelder_mead": {"options": {"xatol": 1e-10, "fatol": 1e-15, "max_iter": 50_000, "initial_step": 10 * step},
                        "max_nfev": 50_000},
        "powell": {"options": {"xtol": 1e-10, "ftol": 1e-15, "initial_step": 10 * step}, "max_nfev": 50_000},
        "cg": {"options": {"max_iter": 2000}, "max_nfev": 50_000},
        "bfgs": {"options": {"ftol": 1e-15, "gtol": 1e-12}, "max_nfev": 50_000},
        "grid": {"options": {"points_per_axis": max(2, int(20_000 ** (1.0 / n)))}, "lb": low, "ub": high},
        "glue": {"options": {"seed": 1, "n_samples": 20_000, "chunk_size": 5000}, "lb": low, "ub": high},
    }
    table["sparse_dud"] = table["dud"]
    return table[method]


def solve(method: str, p: Problem):
    """Run ``method`` (a name of ``rivercal.optimise.OPTIMISERS``) on ``p`` with :func:`settings`."""
    from rivercal.optimise import get_optimiser

    kwargs = dict(settings(method, p))
    lb, ub = kwargs.pop("lb", p.lb), kwargs.pop("ub", p.ub)
    return get_optimiser(method)(p.residuals, p.x0, lb, ub, **kwargs)
