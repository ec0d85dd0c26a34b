"""Observation points and observation cross-sections of a D-Flow FM model as case ``[[stations]]``.

A station is placed by its branch and chainage, by x, y (snapped to the nearest branch) or, given by a polyline, on
the flow link the polyline crosses.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rivercal.io.dhydro._context import Context, unquote

__all__ = ["SNAP_DISTANCE"]

#: Farthest a location given by x, y may lie from a branch to be snapped onto it, m.
SNAP_DISTANCE = 100.0


def _stations(ctx: Context) -> None:
    stations = []
    for blocks in ctx.model.observations:
        for _, oid, reason in blocks.failed:
            ctx.ledger.refused("observation point", oid, reason, hydraulic=False)
        for obs in blocks.objects:
            name = unquote(obs.name)
            where = _locate(ctx, obs.branchid, obs.chainage, obs.x, obs.y, obs)
            if where is None:
                ctx.ledger.refused("observation point", name, f"not on a branch of the network (none within "
                                   f"{SNAP_DISTANCE:g} m)", hydraulic=False)
                continue
            branch, chainage, note = where
            stations.append({"id": ctx.id("station", name), "branch": branch, "chainage": chainage,
                             "quantities": ["h"]})
            ctx.origins[stations[-1]["id"]] = ("observation point", name)
            ctx.source("stations", stations[-1]["id"], obs)
            (ctx.ledger.approximated if note else ctx.ledger.exact)("observation point", name, note)
    for blocks in ctx.model.cross_observations:
        for _, oid, reason in blocks.failed:
            ctx.ledger.refused("observation cross-section", oid, reason, hydraulic=False)
        for oc in blocks.objects:
            name = unquote(oc.name)
            where = _locate(ctx, oc.branchid, oc.chainage, None, None, oc)
            note = ""
            if where is None and getattr(oc, "xcoordinates", None):
                where = _crossing(ctx, oc)
                if where is not None:
                    note = where[2]
            if where is None:
                ctx.ledger.refused("observation cross-section", name, "not on a branch of the network (its branch "
                                   "is unknown, or its polyline crosses no branch)", hydraulic=False)
                continue
            branch, chainage, _ = where
            sid = ctx.id("station", name)
            same = next((st for st in stations if st["id"] == sid), None)
            if same is not None and same["branch"] == branch and abs(same["chainage"] - chainage) < 1e-6:
                same["quantities"].append("Q")  # an observation point and cross-section of one name at one place
                (ctx.ledger.approximated if note else ctx.ledger.exact)("observation cross-section", name, note)
                continue
            if same is not None:
                sid = ctx.id("station", f"{name}_discharge")
            stations.append({"id": sid, "branch": branch, "chainage": chainage, "quantities": ["Q"]})
            ctx.origins[stations[-1]["id"]] = ("observation cross-section", name)
            ctx.source("stations", stations[-1]["id"], oc)
            (ctx.ledger.approximated if note else ctx.ledger.exact)("observation cross-section", name, note)
    ctx.case["stations"] = stations


def _locate(ctx: Context, branch: Any, chainage: Any, x: Any, y: Any, obj: Any = None) -> tuple[str, float, str] | None:
    """Branch id and chainage of a location given on a branch or by x, y (snapped to the nearest branch)."""
    if branch is not None and chainage is not None:
        if not ctx.ids["branch"].known(branch) or ctx.id("branch", branch) not in ctx.branch_length:
            return None
        bid = ctx.id("branch", branch)
        length = ctx.branch_length[bid]
        if float(chainage) > length + max(1.0, 0.01 * length):
            where = ctx.model.sources.where(obj, ctx.model.sources.key_of(obj, "chainage")) if obj is not None else ""
            ctx.ledger.error(where or ctx.model.mdu.name, f"chainage {float(chainage):g} m lies beyond the end of "
                             f"branch {unquote(branch)} ({length:g} m long)")
            return None
        return bid, min(max(float(chainage), 0.0), length), ""
    if x is None or y is None:
        return None
    best = None
    for b in ctx.case["branches"]:
        geo = np.asarray(b.get("geometry") or [], dtype=float)
        if geo.shape[0] < 2:
            continue
        seg = np.diff(geo, axis=0)
        seglen = np.hypot(seg[:, 0], seg[:, 1])
        t = np.clip(((x - geo[:-1, 0]) * seg[:, 0] + (y - geo[:-1, 1]) * seg[:, 1]) / np.maximum(seglen**2, 1e-12),
                    0, 1)
        px, py = geo[:-1, 0] + t * seg[:, 0], geo[:-1, 1] + t * seg[:, 1]
        d = np.hypot(px - x, py - y)
        k = int(np.argmin(d))
        along = (np.concatenate([[0.0], np.cumsum(seglen)])[k] + t[k] * seglen[k]) / max(seglen.sum(), 1e-12)
        if best is None or d[k] < best[0]:
            best = (float(d[k]), b["id"], float(along * b["length"]))
    if best is None or best[0] > SNAP_DISTANCE:
        return None
    return best[1], best[2], f"given by x, y; snapped to the nearest branch {best[1]} ({best[0]:.1f} m away)"


def _crossing(ctx: Context, oc: Any) -> tuple[str, float, str] | None:
    """Where D-Flow FM places an observation cross-section given as a polyline: on the 1D flow link it crosses.

    D-Flow FM (Deltares delft3d, ``crosssections_on_flowgeom`` and ``crspath_on_singlelink`` with
    ``zork = 1``) observes every flow link whose segment between its two calculation points the polyline
    crosses. Where the polyline passes exactly through a calculation point it touches two links; D-Flow FM
    keeps the one the crossing's direction selects (at the link's end point when the cross product of
    polyline and link, −(x43·y21 − y43·x21), is negative, at its start point when it is positive), so that
    the point counts once. The station is put at the middle of the first link the polyline crosses (in the
    polyline's order), where the case reports that link's discharge.
    """
    xs = [float(v) for v in (oc.xcoordinates or [])]
    ys = [float(v) for v in (oc.ycoordinates or [])]
    if len(xs) < 2 or len(xs) != len(ys):
        return None
    poly = np.column_stack([xs, ys])
    found: list[tuple[float, str, float]] = []
    for b in ctx.case["branches"]:
        geo = np.asarray(b.get("geometry") or [], dtype=float)
        points = np.asarray(b.get("points") or [0.0, b["length"]], dtype=float)
        if geo.shape[0] < 2:
            continue
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(geo, axis=0).T))])
        scale = along[-1] / b["length"] if b["length"] > 0 else 1.0
        px = np.interp(points * scale, along, geo[:, 0])
        py = np.interp(points * scale, along, geo[:, 1])
        for k in range(points.size - 1):
            q1, q2 = np.array([px[k], py[k]]), np.array([px[k + 1], py[k + 1]])
            for j in range(len(poly) - 1):
                hit = _crosses(poly[j], poly[j + 1], q1, q2)
                if hit is not None:
                    found.append((j + hit, b["id"], 0.5 * (points[k] + points[k + 1])))
    if not found:
        return None
    found.sort()
    _, branch, chainage = found[0]
    links = {(f[1], f[2]) for f in found}
    note = (f"given by a polyline: placed on the flow link it crosses, as D-Flow FM places it (the middle of the link, "
            f"{chainage:g} m on branch {branch})")
    if len(links) > 1:
        note += (f"; the polyline crosses {len(links)} links, whose discharges D-Flow FM adds up; the station "
                 "reports the first")
    return branch, float(chainage), note


def _crosses(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> float | None:
    """Where polyline segment p1-p2 crosses link q1-q2 (a fraction of p1-p2) by D-Flow FM's rule, or None."""
    x21, y21 = p2 - p1
    x43, y43 = q2 - q1
    x31, y31 = q1 - p1
    det = x43 * y21 - y43 * x21
    eps = max(1e-12 * max(abs(x21), abs(y21), abs(x43), abs(y43), abs(x31), abs(y31)), 1e-300)
    if abs(det) < eps:
        return None
    sm = (y31 * x21 - x31 * y21) / det
    sl = (sm * x43 + x31) / x21 if abs(x21) > eps else (sm * y43 + y31) / y21 if abs(y21) > eps else 0.0
    tol = 1e-9
    if not (-tol <= sm <= 1 + tol and -tol <= sl <= 1 + tol):
        return None
    crp = -det
    if abs(sm - 1.0) <= tol and crp > 0:
        return None
    if abs(sm) <= tol and crp < 0:
        return None
    return float(min(max(sl, 0.0), 1.0))
