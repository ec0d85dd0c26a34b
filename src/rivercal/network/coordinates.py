"""Map coordinates of the network: branch axes, points along them, and where the stations are.

Coordinates are the case's map coordinates in m (its coordinate reference system, when the case
declares one). A branch's axis is its ``geometry`` polyline, else the straight line between its end
nodes (which then need ``x`` and ``y``).
"""

from __future__ import annotations

import numpy as np

from rivercal.network.topology import Network

__all__ = ["MissingCoordinates", "branch_polylines", "point_along", "station_coordinates"]


class MissingCoordinates(ValueError):
    """The network cannot be placed on a map: a branch without geometry has an end node without x/y.

    Map coordinates are optional in a case; what needs them (a map, station coordinates in a NetCDF file)
    catches this and does without.
    """


def branch_polylines(network: Network) -> dict[str, np.ndarray]:
    """Per branch its axis as an (n, 2) array of map coordinates, m."""
    nodes = {n.id: n for n in network.nodes}
    out = {}
    for b in network.branches:
        if b.geometry:
            out[b.id] = np.asarray(b.geometry, dtype=float)
        else:
            a, c = nodes[b.from_node], nodes[b.to_node]
            out[b.id] = np.array([[a.x, a.y], [c.x, c.y]], dtype=float)
    return out


def point_along(xy: np.ndarray, frac: float) -> tuple[float, float]:
    """The point at ``frac`` (0 … 1) of a polyline's length (by arc length), m."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    t = frac * s[-1]
    return float(np.interp(t, s, xy[:, 0])), float(np.interp(t, s, xy[:, 1]))


def station_coordinates(network: Network) -> dict[str, tuple[float, float]]:
    """Map coordinates (m) of every station: at its structure, or at its chainage on its branch.

    Every kind of structure places its station (weirs, culverts, pumps, orifices, universal weirs, bridges).

    Raises
    ------
    MissingCoordinates
        When a branch has no geometry and an end node has no coordinates.
    """
    missing = [n.id for n in network.nodes if n.x is None or n.y is None]
    polylines = {b.id for b in network.branches if b.geometry}
    needed = {end for b in network.branches if b.id not in polylines for end in (b.from_node, b.to_node)}
    if needed & set(missing):
        raise MissingCoordinates(f"node {sorted(needed & set(missing))[0]!r} has no x/y coordinates; the station "
                                 "positions need them (or a geometry for its branches)")
    xy = branch_polylines(network)
    lengths = {b.id: b.length for b in network.branches}
    structures = {s.id: s for s in network.structures}
    out = {}
    for st in network.stations:
        where = structures[st.structure] if st.structure is not None else st
        out[st.id] = point_along(xy[where.branch], where.chainage / lengths[where.branch])
    return out
