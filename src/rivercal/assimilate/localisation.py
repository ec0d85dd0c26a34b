"""Localisation: correlation tapers by distance, and distances along a river network.

An ensemble of N members estimates the covariance between a level here and an observation ten
kilometres away in another tributary with a sampling error of order 1/√N, and the analysis would act
on it. Localisation multiplies each covariance by a taper ρ(d) that is one at distance zero and falls to
zero beyond a cut-off (Houtekamer & Mitchell 2001, Mon. Wea. Rev. 129:123–137; Hamill, Whitaker &
Snyder 2001, Mon. Wea. Rev. 129:2776–2790). On a river the distance that matters is the distance along
the water, not as the crow flies: two branches that run side by side exchange no water except at
their confluence.

The taper is Gaspari & Cohn's (1999, Q. J. R. Meteorol. Soc. 125:723–757, Eq. 4.10) fifth-order
piecewise rational function: compactly supported (zero beyond 2c) and positive definite in Euclidean
space of up to three dimensions, so a tapered covariance matrix stays a covariance matrix there. The
distance along a network is not Euclidean, and for it that guarantee does not carry over. The filters
do not rely on it: the square-root filter localises by weighting each observation's inverse variance
in a local analysis (Hunt, Kostelich & Szunyogh 2007, Physica D 230:112–126, §2.3), which needs no
positive-definite taper, and the stochastic filter adds the observation error covariance R to the
tapered observation-space covariance before inverting it.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

__all__ = ["gaspari_cohn", "network_distances"]


def gaspari_cohn(distance: np.ndarray | float, half_width: float) -> np.ndarray:
    """Gaspari & Cohn's (1999, Eq. 4.10) compactly supported taper ρ(d).

    Parameters
    ----------
    distance
        Distances d ≥ 0 (any unit; m along a network).
    half_width
        c, in the unit of ``distance``: ρ(c) = 5/24 ≈ 0.21 and ρ(d) = 0 for d ≥ 2c. ``inf`` gives 1 everywhere
        (no localisation).

    Returns
    -------
    numpy.ndarray
        ρ(d) in [0, 1], the shape of ``distance``.
    """
    d = np.abs(np.asarray(distance, dtype=float))
    if not half_width > 0:
        raise ValueError(f"localisation half-width must be positive, got {half_width}")
    if np.isinf(half_width):
        return np.ones_like(d)
    r = d / half_width
    out = np.zeros_like(r)
    near = r <= 1.0
    x = r[near]
    out[near] = -0.25 * x**5 + 0.5 * x**4 + 0.625 * x**3 - 5.0 / 3.0 * x**2 + 1.0
    far = (r > 1.0) & (r < 2.0)
    x = r[far]
    out[far] = x**5 / 12.0 - 0.5 * x**4 + 0.625 * x**3 + 5.0 / 3.0 * x**2 - 5.0 * x + 4.0 - 2.0 / (3.0 * x)
    return np.clip(out, 0.0, 1.0)


def network_distances(n_points: int, from_point: np.ndarray, to_point: np.ndarray, length: np.ndarray,
                      sources: np.ndarray | None = None) -> np.ndarray:
    """Shortest distances along the network between its points (Dijkstra over the links, both directions).

    Parameters
    ----------
    n_points
        Number of points (h-points of the engine).
    from_point, to_point
        The two end points of every link.
    length
        Length of every link, m (> 0; a structure link, which is short, counts with the length given).
    sources
        Points to measure from (default all): the rows of the result.

    Returns
    -------
    numpy.ndarray
        Distances, m, shape (len(sources), n_points); ``inf`` between points that no link joins.
    """
    a = np.asarray(from_point, dtype=np.int64)
    b = np.asarray(to_point, dtype=np.int64)
    w = np.asarray(length, dtype=float)
    if not (a.shape == b.shape == w.shape):
        raise ValueError("link end points and lengths must have the same length")
    if w.size and not np.all(w > 0):
        raise ValueError(f"link lengths must be positive; link {int(np.argmin(w))} has {w.min():g} m")
    graph = coo_matrix((w, (a, b)), shape=(n_points, n_points)).tocsr()
    idx = None if sources is None else np.asarray(sources, dtype=np.int64)
    return np.atleast_2d(dijkstra(graph, directed=False, indices=idx))
