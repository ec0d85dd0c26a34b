"""NIST StRD nonlinear regression: DuD, TRF and SCE-UA reach the certified values to ≥ 4 digits.

All lower- and average-difficulty problems, with wide bounds (see ``nist.problem``). Start vectors:

- DuD: NIST start 1 and start 2, every problem; MGH17 from start 1 as a rate over round-off-sized
  changes of the initial perturbation (see ``test_dud_mgh17_start1``);
- TRF (scipy's trust-region reflective method): both starts, every problem. Scaled so that its first trust
  region is one initial step (10 % of |x0|) whatever the distance to the wide bounds, it also solves MGH17,
  Lanczos1, Lanczos2 and Lanczos3 from start 1, where scipy's own TRF (default ``x_scale=1``, whose first
  steps grow with the square root of the distance to the bounds) stops in another local minimum;
- SCE-UA: start 1, except MGH17 (start 2; from start 1 the outcome depends on the seed).
"""

from __future__ import annotations

import pytest

from rivercal.optimise import dud
from tests.optimise.nist import AVERAGE, LOWER, problem, settings, solve

PROBLEMS = LOWER + AVERAGE


def check(method: str, name: str, start: int) -> None:
    p = problem(name, start)
    res = solve(method, p)
    digits = p.digits(res.x)
    assert digits >= 4.0, f"{method} on {name} (start {start}): {digits:.1f} digits, cost {res.cost:.6g} " \
                          f"(certified {p.certified_ssr:.6g}), {res.message}"


@pytest.mark.parametrize(("name", "start"), [(n, s) for n in PROBLEMS for s in (1, 2) if (n, s) != ("MGH17", 1)])
def test_dud(name, start):
    check("dud", name, start)


def test_dud_mgh17_start1():
    """MGH17 (Osborne 1) from NIST start 1: DuD reaches the certified values for most round-off changes.

    From start 1 = (50, 150, −100, 1, 2) the path crosses the valley where the two decay rates b4 and b5
    nearly coincide and the amplitudes b2 ≈ −b3 grow without bound (the model degenerates to a single
    exponential). Whether DuD leaves it toward the certified minimum or crawls along it depends on the last
    bits of the arithmetic: with numpy 2.4.6 / scipy 1.17.1 the NIST settings end at 0.8e-4 cost
    (certified 5.5e-5), and changing the initial perturbation by 1e-9 relative changes the outcome in
    either direction. So the assertion is a rate: of 12 initial perturbations scaled by 1 + k·1e-9, at
    least 9 reach 4 digits (measured: 10 of 12 on that numpy/scipy; 18 of 20 with k up to 19).
    """
    p = problem("MGH17", 1)
    options = settings("dud", p)["options"]
    digits = []
    for k in range(12):
        opts = dict(options, initial_step=options["initial_step"] * (1.0 + 1e-9 * k))
        res = dud(p.residuals, p.x0, p.lb, p.ub, options=opts)
        digits.append(round(p.digits(res.x), 1))
    assert sum(d >= 4.0 for d in digits) >= 9, f"digits per perturbation: {digits}"


def test_dud_with_a_stall_ratio_reaches_the_certified_values_in_fewer_runs():
    """``stall_ratio = 0.01``: a shortened step that gains at most 1 % of its predicted decrease re-initialises.

    Every problem from both starts still reaches 4 digits, except ENSO from start 1 (3.2 digits, where the
    default reaches 5.7) and MGH17 from start 1, whose outcome turns on round-off (see above; 5.9 digits
    with numpy 2.4.6 / scipy 1.17.1). The runs over all of them fall by more than a fifth (measured:
    4,709 against 6,546).
    """
    runs = {"default": 0, "stall": 0}
    short = []
    for name in PROBLEMS:
        for start in (1, 2):
            p = problem(name, start)
            options = settings("dud", p)["options"]
            for kind, opts in (("default", options), ("stall", dict(options, stall_ratio=0.01))):
                res = dud(p.residuals, p.x0, p.lb, p.ub, options=opts)
                runs[kind] += res.nfev
                if kind == "stall" and p.digits(res.x) < 4.0:
                    short.append(f"{name} {start}")
    assert set(short) <= {"ENSO 1", "MGH17 1"}, short
    assert runs["stall"] < 0.8 * runs["default"], runs


@pytest.mark.parametrize(("name", "start"), [(n, s) for n in PROBLEMS for s in (1, 2)])
def test_trf(name, start):
    check("trf", name, start)


@pytest.mark.slow
@pytest.mark.parametrize("name", PROBLEMS)
def test_sce_ua(name):
    check("sce_ua", name, 2 if name == "MGH17" else 1)
