"""The solver plan of a network: elimination order, solve schedule, and the runs the kernels loop over.

All of it depends on the grid's connectivity alone and is computed once per network, never per time
step:

- :func:`connectivity` — the links at each point, and each channel link's neighbour at either end.
- :func:`elimination_order` — the level system that every time step solves is symmetric positive
  definite with the sparsity of the network graph. A minimum-degree order and its symbolic LDLᵀ
  factorisation: on a tree it eliminates leaves first and creates no fill; on looped networks the
  fill entries are added to the pattern here, so the kernels never allocate.
- :func:`solver_schedule` — the factorisation as two independent lanes per step for
  :func:`~rivercal.engine.kernels.solver.ldl_solve_packed`.
- :func:`link_runs` and :func:`momentum_runs` — the links as runs along which points and edges step
  by one, so that the kernels' loops read contiguously and vectorise.

:func:`solver_plan` computes all of them for a network's link arrays.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rivercal.engine.kernels.codes import (
    FRICTION_CHEZY,
    LINK_CHANNEL,
    LINK_PUMP,
    MO_WIDTH,
    NB_JUNCTION,
    NB_NONE,
    NB_OUTFALL,
    RUN_WIDTH,
    SCHED_LANES,
    SCHED_WIDTH,
)

__all__ = [
    "DROP_STEP",
    "SolverPlan",
    "SymbolicLDL",
    "connectivity",
    "drop_links",
    "elimination_order",
    "link_runs",
    "momentum_runs",
    "solver_plan",
    "solver_schedule",
]


def connectivity(n_points: int, lk_k1: np.ndarray, lk_k2: np.ndarray, lk_type: np.ndarray) -> tuple:
    """The links at each h-point, and each channel link's neighbour at either end.

    Parameters
    ----------
    n_points
        Number of h-points.
    lk_k1, lk_k2, lk_type
        Per link: its two h-points and its type code.

    Returns
    -------
    tuple
        ``nl_ptr``, ``nl_link``, ``nl_sign`` — the links at each point (CSR; sign +1 when the link ends
        there, -1 when it starts there); ``lk_nb``, ``lk_ns`` — per end (rows k1, k2) and link: the one
        other link at that end when it is the only one and a channel (``NB_JUNCTION`` when two or more
        others meet there, ``NB_NONE`` for none or a structure), and its sign there.
    """
    n_l = lk_k1.size
    at: list[list[tuple[int, int]]] = [[] for _ in range(n_points)]
    for li in range(n_l):
        at[int(lk_k1[li])].append((li, -1))
        at[int(lk_k2[li])].append((li, +1))
    nl_ptr = np.zeros(n_points + 1, dtype=np.int64)
    nl_ptr[1:] = np.cumsum([len(a) for a in at])
    nl_link = np.array([li for a in at for li, _ in a], dtype=np.int64)
    nl_sign = np.array([sg for a in at for _, sg in a], dtype=np.int64)
    lk_nb = np.full((2, n_l), NB_NONE, dtype=np.int64)
    lk_ns = np.zeros((2, n_l), dtype=np.int64)
    for li in range(n_l):
        for end, k in enumerate((int(lk_k1[li]), int(lk_k2[li]))):
            others = [(lj, sg) for lj, sg in at[k] if lj != li]
            if len(others) > 1:
                lk_nb[end, li] = NB_JUNCTION
            elif len(others) == 1 and lk_type[others[0][0]] == LINK_CHANNEL:
                lk_nb[end, li], lk_ns[end, li] = others[0]
    return nl_ptr, nl_link, nl_sign, lk_nb, lk_ns


@dataclass(frozen=True)
class SolverPlan:
    """What the kernels need to solve and loop over a network (see :func:`solver_plan`).

    Attributes
    ----------
    symbolic
        The elimination order and fill pattern of the level matrix.
    schedule
        :func:`solver_schedule` of it (``uint32``).
    link_edge
        Solver edge of each link (-1 for a pump, which does not couple its points).
    link_runs
        :func:`link_runs` (``uint64`` rows).
    momentum_runs, momentum_other
        :func:`momentum_runs` (``uint64``).
    """

    symbolic: SymbolicLDL
    schedule: np.ndarray
    link_edge: np.ndarray
    link_runs: np.ndarray
    momentum_runs: np.ndarray
    momentum_other: np.ndarray


#: A channel link whose bed ends more than this (m) above the bed of its end point ends in a drop.
DROP_STEP = 0.01


def drop_links(lk_type: np.ndarray, lk_k1: np.ndarray, lk_k2: np.ndarray, lk_b1: np.ndarray, lk_b2: np.ndarray,
               hp_bed: np.ndarray) -> np.ndarray:
    """The channel links whose bed ends above the bed of an end point by more than ``DROP_STEP`` (m), in order.

    Water leaving such a link can fall freely over the step (:mod:`rivercal.engine.kernels.overfall`). Beds in
    m AD: ``lk_b1``, ``lk_b2`` at the link's two ends, ``hp_bed`` the lowest bed at each point.
    """
    channel = lk_type == LINK_CHANNEL
    step = (lk_b1 > hp_bed[lk_k1] + DROP_STEP) | (lk_b2 > hp_bed[lk_k2] + DROP_STEP)
    return np.flatnonzero(channel & step).astype(np.int64)


def solver_plan(n_points: int, lk_type: np.ndarray, lk_k1: np.ndarray, lk_k2: np.ndarray, lk_nb: np.ndarray,
                lk_ns: np.ndarray, lk_ftype: np.ndarray, level_points: np.ndarray,
                lateral_points: np.ndarray) -> SolverPlan:
    """Elimination order, schedule, link edges and runs of a network's links.

    Parameters
    ----------
    n_points
        Number of h-points.
    lk_type, lk_k1, lk_k2
        Per link: its type (``LINK_*`` of :mod:`.kernels.codes`) and its two h-points.
    lk_nb, lk_ns, lk_ftype
        See :func:`momentum_runs`.
    level_points
        The h-points with a level boundary (their links are assembled apart).
    lateral_points
        The h-points that receive a lateral.
    """
    coupling = lk_type != LINK_PUMP
    sym = elimination_order(n_points, list(zip(lk_k1[coupling].tolist(), lk_k2[coupling].tolist(), strict=True)))
    link_edge = np.full(lk_type.size, -1, dtype=np.int64)
    for li in np.flatnonzero(coupling):
        link_edge[li] = sym.edge_of[_key(int(lk_k1[li]), int(lk_k2[li]))]
    general = ~coupling | np.isin(lk_k1, level_points) | np.isin(lk_k2, level_points)
    mo_runs, mo_other = momentum_runs(lk_type, lk_k1, lk_k2, lk_nb, lk_ns, lk_ftype, lateral_points)
    return SolverPlan(
        symbolic=sym,
        schedule=solver_schedule(sym),
        link_edge=link_edge,
        link_runs=link_runs(lk_k1, lk_k2, link_edge, general),
        momentum_runs=mo_runs,
        momentum_other=mo_other,
    )


def _key(i: int, j: int) -> tuple[int, int]:
    return (i, j) if i < j else (j, i)


@dataclass(frozen=True)
class SymbolicLDL:
    """Elimination order and the fill pattern of the level matrix.

    Attributes
    ----------
    order
        h-points in elimination order.
    cptr, cedge, cother
        For the point eliminated at position p: its edges to later points (``cedge``) and those
        points (``cother``) in ``cptr[p]:cptr[p+1]``.
    uptr, ue1, ue2, utgt
        Schur-complement updates of position p: ``a[t] -= l[e1] * a[e2]`` where t ≥ 0 is an edge
        and t < 0 is the diagonal of point ``-1 - t``.
    edge_of
        Edge index of each original or fill pair (i, j), i < j.
    n_edges
        Number of edges, fill included.
    fill
        Number of fill edges (0 on a tree).
    """

    order: np.ndarray
    cptr: np.ndarray
    cedge: np.ndarray
    cother: np.ndarray
    uptr: np.ndarray
    ue1: np.ndarray
    ue2: np.ndarray
    utgt: np.ndarray
    edge_of: dict[tuple[int, int], int]
    n_edges: int
    fill: int


def elimination_order(n: int, pairs: Sequence[tuple[int, int]]) -> SymbolicLDL:
    """Minimum-degree elimination order and symbolic factorisation of a graph Laplacian-like matrix.

    Parameters
    ----------
    n
        Number of unknowns (h-points).
    pairs
        Off-diagonal pairs (links); duplicates and orientation do not matter.

    Returns
    -------
    SymbolicLDL
        The order, the column structure of L and the update lists. On a tree the order
        eliminates leaves first and ``fill == 0``.
    """
    adj: list[set[int]] = [set() for _ in range(n)]
    edge_of: dict[tuple[int, int], int] = {}
    for i, j in pairs:
        if i == j:
            continue
        k = _key(i, j)
        if k not in edge_of:
            edge_of[k] = len(edge_of)
        adj[i].add(j)
        adj[j].add(i)
    n_original = len(edge_of)
    heap = [(len(adj[i]), 0, i) for i in range(n)]
    heapq.heapify(heap)
    eliminated = np.zeros(n, dtype=bool)
    gen_of = np.zeros(n, dtype=np.int64)
    order: list[int] = []
    later: list[list[int]] = []
    while heap:
        deg, gen, i = heapq.heappop(heap)
        if eliminated[i] or deg != len(adj[i]) or gen != gen_of[i]:
            continue
        eliminated[i] = True
        order.append(i)
        nbrs = sorted(adj[i])
        later.append(nbrs)
        for a in nbrs:
            adj[a].discard(i)
        for x in range(len(nbrs)):
            for y in range(x + 1, len(nbrs)):
                a, b = nbrs[x], nbrs[y]
                if b not in adj[a]:
                    adj[a].add(b)
                    adj[b].add(a)
                    edge_of[_key(a, b)] = len(edge_of)
        # Of the points of least degree, those of the earliest round go first. The points whose entries this
        # elimination updates, and their neighbours, move to the next round: the eliminations of one round
        # touch no entry in common, so the solver can run them side by side (on a loop of the network the
        # order goes round it in rounds instead of point after point: a dependency chain of the length of the loop
        # became one of some dozen rounds). A point whose degree changed gets a fresh entry.
        near = set(nbrs)
        for a in nbrs:
            near.update(adj[a])
        for a in near:
            later_round = gen_of[a] <= gen
            if later_round:
                gen_of[a] = gen + 1
            if later_round or a in nbrs:
                heapq.heappush(heap, (len(adj[a]), int(gen_of[a]), a))
    cptr, cedge, cother = [0], [], []
    uptr, ue1, ue2, utgt = [0], [], [], []
    for nbrs, i in zip(later, order, strict=True):
        edges = [edge_of[_key(i, j)] for j in nbrs]
        cedge.extend(edges)
        cother.extend(nbrs)
        cptr.append(len(cedge))
        for x, (ex, jx) in enumerate(zip(edges, nbrs, strict=True)):
            ue1.append(ex)
            ue2.append(ex)
            utgt.append(-1 - jx)
            for ey, jy in zip(edges[x + 1 :], nbrs[x + 1 :], strict=True):
                ue1.append(ex)
                ue2.append(ey)
                utgt.append(edge_of[_key(jx, jy)])
        uptr.append(len(ue1))
    as_int = lambda v: np.asarray(v, dtype=np.int64)  # noqa: E731
    return SymbolicLDL(
        order=as_int(order),
        cptr=as_int(cptr),
        cedge=as_int(cedge),
        cother=as_int(cother),
        uptr=as_int(uptr),
        ue1=as_int(ue1),
        ue2=as_int(ue2),
        utgt=as_int(utgt),
        edge_of=edge_of,
        n_edges=len(edge_of),
        fill=len(edge_of) - n_original,
    )


def solver_schedule(sym: SymbolicLDL) -> np.ndarray:
    """The symbolic factorisation as a schedule for :func:`~rivercal.engine.kernels.solver.ldl_solve_packed`.

    Along a branch every elimination depends on the previous one, so the solve is bound by the latency of
    that chain; independent eliminations in one step (up to ``SCHED_LANES``) let the processor overlap their
    chains. A step holds ``SCHED_LANES`` lanes of ``SCHED_WIDTH`` unsigned integers: the point eliminated (``n``:
    the lane is empty), the number m of its later neighbours, their edges and points when m is 1 or 2
    (``k, m, e1, o1, e2, o2``), then the edge between the two (m = 2) or the elimination position in ``sym``
    (m > 2, read from the CSR arrays; such a step has one lane, the first), and which later point the lane
    carries to its next step (0: o1, 1: o2, 2: none).

    Eliminations share a step only when none touches an entry (pivot, later point, edge, fill target) that
    another touches, and every entry is updated by the same eliminations in the same order as in ``sym.order``:
    the result is bit-identical to the one-lane solve. The steps follow a list schedule by longest remaining
    chain, keeping each chain in its lane so that the value it updates stays in a register (the "carry").

    Parameters
    ----------
    sym
        The symbolic factorisation of :func:`elimination_order`.

    Returns
    -------
    numpy.ndarray
        ``uint32`` array of ``SCHED_LANES * SCHED_WIDTH`` entries per step (half the bytes of ``uint64``: at board
        size the solve streams it from memory every step).
    """
    n = sym.order.size
    touches: list[set[tuple[str, int]]] = []
    for p in range(n):
        ent = {("h", int(sym.order[p]))}
        for c in range(sym.cptr[p], sym.cptr[p + 1]):
            ent.add(("h", int(sym.cother[c])))
            ent.add(("e", int(sym.cedge[c])))
        ent.update(("e", int(t)) for t in sym.utgt[sym.uptr[p] : sym.uptr[p + 1]] if t >= 0)
        touches.append(ent)
    after: list[list[int]] = [[] for _ in range(n)]  # eliminations that must wait for p
    waits = np.zeros(n, dtype=np.int64)
    last: dict[tuple[str, int], int] = {}
    for p in range(n):
        for ent in touches[p]:
            q = last.get(ent)
            if q is not None and p not in after[q]:
                after[q].append(p)
                waits[p] += 1
            last[ent] = p
    chain = np.ones(n, dtype=np.int64)  # longest chain of waiting eliminations from p on
    for p in range(n - 1, -1, -1):
        for s in after[p]:
            chain[p] = max(chain[p], chain[s] + 1)
    width = sym.cptr[1:] - sym.cptr[:-1]
    position = np.empty(n, dtype=np.int64)
    position[sym.order] = np.arange(n)
    ready = [(-int(chain[p]), p) for p in range(n) if waits[p] == 0]
    heapq.heapify(ready)
    steps: list[list[np.ndarray]] = []
    carried = [n] * SCHED_LANES  # the point each lane carries into its next step
    while ready:
        first = heapq.heappop(ready)[1]
        take = [first]
        while width[first] <= 2 and len(take) < SCHED_LANES and ready and width[ready[0][1]] <= 2:
            take.append(heapq.heappop(ready)[1])
        lanes: list[int | None] = [None] * SCHED_LANES
        if width[first] > 2:  # alone, in the first lane (the solver reads the CSR arrays for it there)
            lanes[0] = first
        else:
            for p in take:  # an elimination of a carried point goes to the lane that carries it
                if int(sym.order[p]) in carried:
                    lanes[carried.index(int(sym.order[p]))] = p
            for p in take:
                if p not in lanes:
                    lanes[lanes.index(None)] = p
        step = []
        for lane, p in enumerate(lanes):
            rec = np.zeros(SCHED_WIDTH, dtype=np.uint32)
            rec[0], rec[7] = n, 2
            carried[lane] = n
            if p is not None:
                c0, m = sym.cptr[p], int(width[p])
                rec[0], rec[1] = sym.order[p], m
                if m in (1, 2):
                    rec[2], rec[3] = sym.cedge[c0], sym.cother[c0]
                if m == 2:  # the updates of a two-neighbour step are (o1, o1), (o1, o2), (o2, o2)
                    rec[4], rec[5] = sym.cedge[c0 + 1], sym.cother[c0 + 1]
                    rec[6] = sym.utgt[sym.uptr[p] + 1]
                elif m > 2:
                    rec[6] = p
                if m in (1, 2):  # carry the later point that is eliminated first
                    rec[7] = 0 if m == 1 or position[sym.cother[c0]] < position[sym.cother[c0 + 1]] else 1
                    carried[lane] = int(rec[3 + 2 * rec[7]])
            step.append(rec)
        steps.append(step)
        for p in take:
            for s in after[p]:
                waits[s] -= 1
                if waits[s] == 0:
                    heapq.heappush(ready, (-int(chain[s]), s))
    return np.array(steps, dtype=np.uint32).ravel()


def link_runs(lk_k1: np.ndarray, lk_k2: np.ndarray, lk_edge: np.ndarray, general: np.ndarray) -> np.ndarray:
    """The links, in order, as runs along which both end points and the solver edge step by one.

    The calculation points and links of a branch are numbered along it, so a branch's links form a few
    long runs: link ``l + j`` of a run joins points ``k1 + j`` and ``k2 + j`` and has solver edge ``e + j``.
    A kernel that loops over a run reads and writes the point arrays contiguously instead of gathering and
    scattering through ``lk_k1``/``lk_k2``, and the compiler vectorises it. A ``general`` link (a pump, or
    a link at a level-boundary point, which the assembly treats apart) is a run of its own, flagged.

    Parameters
    ----------
    lk_k1, lk_k2, lk_edge
        Per link: its two h-points and its solver edge (-1 for a pump).
    general
        Per link: whether it must be a run of its own.

    Returns
    -------
    numpy.ndarray
        ``uint64`` array, one row per run: first link, number of links, first k1, first k2, first edge (0 for
        a pump), general flag (columns ``RUN_LINK`` … ``RUN_GENERAL``). The runs cover every link once, in order.
    """
    rows = []
    n = lk_k1.size
    link = 0
    while link < n:
        end = link + 1
        if not general[link]:
            while (end < n and not general[end] and lk_k1[end] - lk_k1[link] == end - link
                   and lk_k2[end] - lk_k2[link] == end - link and lk_edge[end] - lk_edge[link] == end - link):
                end += 1
        rows.append((link, end - link, lk_k1[link], lk_k2[link], max(int(lk_edge[link]), 0), int(general[link])))
        link = end
    return np.array(rows, dtype=np.uint64).reshape(-1, RUN_WIDTH)


def momentum_runs(lk_type: np.ndarray, lk_k1: np.ndarray, lk_k2: np.ndarray, lk_nb: np.ndarray,
                  lk_ns: np.ndarray, lk_ftype: np.ndarray, lateral_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The channel links whose momentum terms a branch-free, contiguous loop can compute, as runs; the others.

    Inside a branch a channel link ``l`` joins consecutive points (k2 = k1 + 1) and its upwind neighbour is
    the next channel link along the branch on either side: link ``l - 1`` ending at k1, link ``l + 1``
    starting at k2. For such *simple* links the momentum pass reads the levels, the neighbours' velocities
    and fluxes contiguously (:func:`rivercal.engine.kernels.momentum.channel_coefficients`). A channel link
    next to a junction, a structure, a branch end or a lateral, or with Chézy friction (whose hydraulic
    radius costs a division that the others do not need; White-Colebrook too), or next to a free outfall, is one
    of the others.

    Parameters
    ----------
    lk_type, lk_k1, lk_k2
        Per link: its type and its two h-points.
    lk_nb, lk_ns
        Per end (rows) and link: the one other channel link at that end (-1 junction, -2 none or a
        structure) and +1 if it ends there, -1 if it starts there.
    lk_ftype
        Per link: its friction type (``FRICTION_*`` of :mod:`.kernels.codes`).
    lateral_points
        The h-points that receive a lateral.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``uint64`` rows (first link, number of links, k1 of the first link) of the runs of simple links,
        and the other channel links (``uint64``).
    """
    n = lk_type.size
    index = np.arange(n)
    outfall = (lk_nb == NB_OUTFALL).any(axis=0)  # the links that reach a free outfall, and the links feeding them
    feeding = np.isin(index, lk_nb[:, outfall][lk_nb[:, outfall] >= 0])
    simple = ((lk_type == LINK_CHANNEL) & (lk_k2 == lk_k1 + 1) & (lk_nb[0] == index - 1) & (lk_ns[0] == 1)
              & (lk_nb[1] == index + 1) & (lk_ns[1] == -1) & (lk_ftype < FRICTION_CHEZY)
              & ~np.isin(lk_k1, lateral_points) & ~np.isin(lk_k2, lateral_points) & ~outfall & ~feeding)
    rows = []
    link = 0
    while link < n:
        if not simple[link]:
            link += 1
            continue
        end = link + 1
        while end < n and simple[end]:
            end += 1
        rows.append((link, end - link, lk_k1[link]))
        link = end
    other = np.flatnonzero((lk_type == LINK_CHANNEL) & ~simple)
    return np.array(rows, dtype=np.uint64).reshape(-1, MO_WIDTH), other.astype(np.uint64)
