"""Parameters: transforms (thesis Eq. 2-8, 2-9), clusters, vector ↔ quantities, and validation messages."""

import math

import numpy as np
import pytest
from pydantic import ValidationError

from rivercal.case import load_case
from rivercal.parameters import ClusterTarget, Parameter, ParameterSet

WEIRS = [("A", 9.9, 11.74, 10.82), ("B", 6.84, 7.45, 7.145)]


def _cluster(mode: str, **kw) -> Parameter:
    return Parameter(name="W", cluster=[ClusterTarget(target=f"weir:{n}.crest_level", min=lo, max=hi, base=b)
                                        for n, lo, hi, b in WEIRS], cluster_mode=mode, perturbation=0.1, **kw)


def test_fraction_cluster_places_each_crest_in_its_own_range() -> None:
    p = _cluster("fraction", min=0.0, max=1.0, initial=0.5)
    q = p.quantities(0.25)
    assert q["weir:A.crest_level"] == pytest.approx(9.9 + 0.25 * 1.84)
    assert q["weir:B.crest_level"] == pytest.approx(6.84 + 0.25 * 0.61)


def test_shift_cluster_moves_every_crest_alike_from_its_base() -> None:
    p = _cluster("shift", min=-0.3, max=0.3, initial=0.0)
    assert p.quantities(0.0) == {"weir:A.crest_level": 10.82, "weir:B.crest_level": 7.145}
    q = p.quantities(-0.15)
    assert q["weir:A.crest_level"] == pytest.approx(10.67) and q["weir:B.crest_level"] == pytest.approx(6.995)


def test_shift_cluster_bounds_must_keep_crests_in_range() -> None:
    with pytest.raises(ValidationError, match=r"weir:B.crest_level from 7.145 outside its range \[6.84, 7.45\]"):
        _cluster("shift", min=-0.4, max=0.3, initial=0.0)
    with pytest.raises(ValidationError, match="needs a base crest level"):
        Parameter(name="W", cluster=[ClusterTarget(target="weir:A.crest_level", min=9.9, max=11.7)],
                  cluster_mode="shift", min=-0.1, max=0.1, initial=0.0, perturbation=0.05)


def test_transforms_and_first_steps() -> None:
    off = Parameter(name="a", targets=["friction:global"], min=8, max=40, initial=16, perturbation=1.5)
    fac = off.model_copy(update={"transform": "factor", "perturbation": 0.1})
    ln = off.model_copy(update={"transform": "ln", "perturbation": 0.1})
    assert off.initial_step(16.0) == 1.5  # Eq. 2-8: θ₀ + λ
    assert fac.initial_step(16.0) == pytest.approx(1.6)  # Eq. 2-9: θ₀ + λθ₀
    assert ln.to_x(16.0) == pytest.approx(math.log(16.0)) and ln.from_x(ln.to_x(20.0)) == pytest.approx(20.0)


def test_set_maps_vectors_names_and_quantities() -> None:
    ps = ParameterSet([
        Parameter(name="FA", targets=["friction:global"], min=8, max=40, initial=16, perturbation=1.5),
        _cluster("shift", min=-0.3, max=0.3, initial=0.0),
    ])
    x = np.array([25.0, -0.15])
    assert ps.values(x) == {"FA": 25.0, "W": -0.15}
    q = ps.quantities(ps.values(x))
    assert q["friction:global"] == 25.0 and q["weir:B.crest_level"] == pytest.approx(6.995)
    lb, ub = ps.bounds()
    assert lb.tolist() == [8.0, -0.3] and ub.tolist() == [40.0, 0.3]
    # bounds stay physical when the start changes (OpenDA issue 337)
    moved = ps.with_initial({"FA": 30.0})
    assert moved["FA"].initial == 30.0 and moved.bounds()[0].tolist() == [8.0, -0.3]


def test_a_quantity_set_by_two_parameters_is_refused() -> None:
    a = Parameter(name="W2", targets=["weir:A.crest_level"], min=9.9, max=11.7, initial=10.8, perturbation=0.1)
    with pytest.raises(ValueError, match=r"weir:A\.crest_level is set by both 'W2' and 'W'"):
        ParameterSet([a, _cluster("shift", min=-0.3, max=0.3, initial=0.0)])


def test_dommel_wd_is_zero_at_the_dss_crests() -> None:
    case = load_case("dommel")
    params = {p.name: p for p in case.spec.parameters}
    weirs = {w.id: w.crest_level for w in case.network.weirs}
    q = params["Wd"].quantities(0.0)
    assert len(q) == 9
    assert all(weirs[t.split(":")[1].removesuffix(".crest_level")] == v for t, v in q.items())
