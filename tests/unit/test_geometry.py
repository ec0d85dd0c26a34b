"""Profile tables against closed-form geometry."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.engine.geometry import build_tables, flow_records, zw_of
from rivercal.engine.kernels.lookup import flow_geometry, storage_area_width
from rivercal.network import RectangularProfile, TrapezoidalProfile, ZWProfile


def _lookup(tables, p, d, compiled=True):
    fg = flow_geometry if compiled else flow_geometry.py_func
    sa = storage_area_width if compiled else storage_area_width.py_func
    a, per, r43 = fg(tables.off, tables.n, 1 / tables.dd, tables.top, tables.wf_top, tables.af, tables.pf,
                     flow_records(tables), p, d)
    at, wt = sa(tables.off, tables.n, tables.dd, 1 / tables.dd, tables.top, tables.wt_top, tables.at, tables.wt, p, d)
    return a, per, r43, at, wt


@pytest.mark.parametrize("compiled", [True, False], ids=["numba", "py_func"])
@pytest.mark.parametrize("depth", [0.013, 0.5, 1.7312, 4.0, 12.5])
def test_trapezoid_matches_formulas(depth: float, compiled: bool) -> None:
    b, m = 4.0, 1.5
    tables = build_tables([zw_of(TrapezoidalProfile(id="t", type="trapezoidal", bottom_width=b, side_slope=m))])
    a, per, r43, at, wt = _lookup(tables, 0, depth, compiled)
    area = (b + m * depth) * depth
    perimeter = b + 2 * depth * np.sqrt(1 + m * m)
    if depth > tables.top[0]:  # vertical walls above the table top (10 m)
        top = tables.top[0]
        width_top = b + 2 * m * top
        area = (b + m * top) * top + width_top * (depth - top)
        perimeter = b + 2 * top * np.sqrt(1 + m * m) + 2 * (depth - top)
    # linear interpolation of the quadratic area m d² + b d errs by at most m δ²/4 within a cell
    tolerance = m * tables.dd[0] ** 2 / 4 + 1e-12
    assert abs(a - area) <= tolerance
    assert abs(at - area) <= tolerance
    assert per == pytest.approx(perimeter, rel=1e-9)
    assert r43 == pytest.approx((area / perimeter) ** (4 / 3), rel=2e-4 if depth > 0.1 else 2e-2)
    assert wt == pytest.approx(b + 2 * m * min(depth, tables.top[0]), rel=2e-3)


def test_rectangle_is_exact_and_zw_is_consistent() -> None:
    rect = zw_of(RectangularProfile(id="r", type="rectangular", width=6.0))
    zw = zw_of(ZWProfile(id="z", type="zw", heights=[0, 1, 3], flow_widths=[2, 4, 4], total_widths=[2, 8, 10]))
    tables = build_tables([rect, zw])
    a, per, _, at, wt = _lookup(tables, 0, 2.345)
    assert (a, per, at, wt) == pytest.approx((6 * 2.345, 6 + 2 * 2.345, 6 * 2.345, 6.0), rel=1e-12)
    # ZW: flow area = trapezoid 2→4 over 1 m (3 m²) + 4 m × 0.5 m; total = 5 m² + (8 + 8.5) / 2 × 0.5
    a, per, _, at, _ = _lookup(tables, 1, 1.5)
    assert a == pytest.approx(3.0 + 2.0, rel=1e-6)
    assert at == pytest.approx(5.0 + 0.5 * (8 + 8.5) * 0.5, rel=1e-6)
    assert per == pytest.approx(2 + 2 * np.hypot(1, 1) + 2 * 0.5, rel=1e-9)


def test_storage_width_is_the_slope_of_the_volume() -> None:
    """Volume and width are exactly consistent: V(d + h) - V(d) = w h within one table cell."""
    tables = build_tables([zw_of(TrapezoidalProfile(id="t", type="trapezoidal", bottom_width=3, side_slope=2))])
    dd = tables.dd[0]
    d0 = 37 * dd + 0.1 * dd
    at0, w0 = _lookup(tables, 0, d0)[3:]
    at1, _ = _lookup(tables, 0, d0 + 0.8 * dd)[3:]
    assert at1 - at0 == pytest.approx(w0 * 0.8 * dd, rel=1e-12)
