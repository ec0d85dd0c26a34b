"""Network → flat arrays: the computational grid, geometry tables and the solver's elimination order.

This runs once per network (not per run, never per time step). The grid is staggered: levels at
*h-points* (connection nodes and the calculation points inside branches), discharges at *links*
between consecutive h-points of a branch. A structure occupies its own short link of length
``structure_length`` centred on its chainage, so the h-points at the ends of that link carry the
levels just up- and downstream of it.

The level system that every time step solves is symmetric positive definite with the sparsity of
the network graph. :func:`elimination_order` computes a minimum-degree order and its symbolic
LDLᵀ factorisation once: on a tree it eliminates leaves first and creates no fill; on looped
networks the fill entries are added to the pattern here, so the kernels never allocate.
"""

from __future__ import annotations

import heapq
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from rivercal.case.schema import EngineSettings, StructureOverlap, branch_layout
from rivercal.engine.geometry import ProfileTables, build_tables, storage_zw, zw_of
from rivercal.errors import CaseError
from rivercal.network import Branch, Culvert, Network, Weir

__all__ = [
    "BOUNDARY_DISCHARGE",
    "BOUNDARY_LEVEL",
    "BOUNDARY_RATING",
    "LINK_CHANNEL",
    "LINK_CULVERT",
    "LINK_PUMP",
    "LINK_WEIR",
    "RUN_COUNT",
    "RUN_EDGE",
    "RUN_GENERAL",
    "RUN_K1",
    "RUN_K2",
    "RUN_LINK",
    "CompiledNetwork",
    "NetArrays",
    "compile_network",
    "elimination_order",
    "flow_records",
    "link_runs",
    "momentum_runs",
    "solver_schedule",
]

LINK_CHANNEL, LINK_WEIR, LINK_CULVERT, LINK_PUMP = 0, 1, 2, 3
BOUNDARY_DISCHARGE, BOUNDARY_LEVEL, BOUNDARY_RATING = 0, 1, 2
FRICTION_CODES = {"strickler": 0, "manning": 1, "chezy": 2}
DIRECTION_CODES = {"both": 0, "positive": 1, "negative": 2, "none": 3}
OBS_LEVEL, OBS_FLUX = 0, 1


class NetArrays(NamedTuple):
    """Everything the kernels know about the network (flat arrays; see :mod:`rivercal.engine.kernels`)."""

    # h-points
    hp_bed: np.ndarray  # lowest bed level at the point, m AD
    hp_amin: np.ndarray  # minimum storage area, m²
    hp_ilen: np.ndarray  # 1 / channel length represented by the point, 1/m (0 for a point without channel)
    sc_ptr: np.ndarray  # storage contributions of each h-point (CSR)
    sc_prof: np.ndarray
    sc_bed: np.ndarray  # bed level of the contribution, m AD
    sc_len: np.ndarray  # channel length it represents, m (1 for node storage)
    nl_ptr: np.ndarray  # links at each h-point (CSR)
    nl_link: np.ndarray
    nl_sign: np.ndarray  # +1 when the link ends at the point, -1 when it starts there
    # links
    lk_k1: np.ndarray
    lk_k2: np.ndarray
    lk_type: np.ndarray
    lk_len: np.ndarray  # m
    lk_ilen: np.ndarray  # 1/m
    lk_p1: np.ndarray  # profile at the k1 end
    lk_b1: np.ndarray  # bed at the k1 end, m AD
    lk_p2: np.ndarray
    lk_b2: np.ndarray
    lk_fric: np.ndarray  # friction group (branch index)
    lk_sidx: np.ndarray  # index in the weir/culvert/pump arrays
    lk_edge: np.ndarray  # solver edge, -1 for pumps
    lk_nb1: np.ndarray  # the one other channel link at k1 (-1: junction, -2: none or a structure)
    lk_ns1: np.ndarray  # +1 if that link ends at k1, -1 if it starts there
    lk_nb2: np.ndarray  # same at k2
    lk_ns2: np.ndarray
    lk_runs: np.ndarray  # the links as runs along which k1, k2 and the edge step by one (uint64, see link_runs)
    lk_ftype: np.ndarray  # friction type of the link's group (FRICTION_CODES)
    mo_runs: np.ndarray  # runs of channel links whose momentum terms vectorise (uint64, see momentum_runs)
    mo_other: np.ndarray  # the other channel links (uint64)
    # profile tables
    tab_off: np.ndarray
    tab_n: np.ndarray
    tab_dd: np.ndarray
    tab_idd: np.ndarray  # 1/m
    tab_af: np.ndarray
    tab_pf: np.ndarray
    tab_at: np.ndarray
    tab_wt: np.ndarray  # storage width per cell, m
    tab_wf_top: np.ndarray
    tab_wt_top: np.ndarray
    tab_top: np.ndarray
    tab_flow: np.ndarray  # per table cell: af, pf and r43 and their increments to the next cell (FLOW_WIDTH values)
    # friction groups
    fr_type: np.ndarray
    # weirs
    w_width: np.ndarray  # m
    w_cmu: np.ndarray  # c_e * c_w
    w_dir: np.ndarray
    # culverts
    c_shape: np.ndarray  # 0 rectangular, 1 circular
    c_width: np.ndarray  # m (diameter for circular)
    c_height: np.ndarray  # m
    c_invert: np.ndarray  # m AD
    c_length: np.ndarray  # m
    c_xin: np.ndarray
    c_xout: np.ndarray
    c_ftype: np.ndarray
    c_fval: np.ndarray
    c_dir: np.ndarray
    # pumps
    p_cap: np.ndarray  # m³/s
    p_on: np.ndarray  # m AD
    p_off: np.ndarray  # m AD
    p_sign: np.ndarray  # +1 branch direction, -1 against
    # boundaries
    b_hp: np.ndarray
    b_type: np.ndarray
    b_col: np.ndarray  # forcing column, -1 for rating boundaries
    b_rptr: np.ndarray  # rating tables (CSR)
    b_rlev: np.ndarray
    b_rq: np.ndarray
    # laterals
    lat_hp: np.ndarray
    lat_col: np.ndarray
    # solver (symbolic LDLᵀ)
    sv_order: np.ndarray
    sv_cptr: np.ndarray
    sv_cedge: np.ndarray
    sv_cother: np.ndarray
    sv_uptr: np.ndarray
    sv_ue1: np.ndarray
    sv_ue2: np.ndarray
    sv_utgt: np.ndarray
    sv_nedge: int
    sv_sched: np.ndarray  # the same as a two-lane schedule for ldl_solve_packed (uint64, see solver_schedule)
    # observables
    ob_type: np.ndarray
    ob_i1: np.ndarray
    ob_i2: np.ndarray
    ob_w: np.ndarray


@dataclass(frozen=True)
class CompiledNetwork:
    """The flat kernel arrays plus the index maps that translate names to positions.

    Attributes
    ----------
    arrays
        Kernel input.
    hp_label, hp_branch, hp_chainage, hp_xy
        Per h-point: label, branch id ("" for nodes), chainage (m; nan for nodes), map position (m).
    link_label, link_branch, link_chainage
        Per link: label, branch id, chainage of its midpoint (m).
    structure_link
        Link index of each structure id.
    weir_ids, branch_ids
        Order of the weir and friction-group (branch) arrays.
    branch_inherits
        Branch ids that use the global friction.
    boundary_ids, lateral_ids
        Order of the boundaries and laterals; ``forcing_keys`` is the column order of the
        forcing matrix (``"boundary:<id>"``, ``"lateral:<id>"``) and ``forcing_is_level`` tells
        which columns hold levels (m AD) rather than discharges (m³/s).
    observables
        Names of the simulated series, in kernel order.
    """

    arrays: NetArrays
    hp_label: list[str]
    hp_branch: list[str]
    hp_chainage: np.ndarray
    hp_xy: np.ndarray
    link_label: list[str]
    link_branch: list[str]
    link_chainage: np.ndarray
    structure_link: dict[str, int]
    weir_ids: list[str]
    branch_ids: list[str]
    branch_inherits: list[str]
    boundary_ids: list[str]
    lateral_ids: list[str]
    forcing_keys: list[str]
    forcing_is_level: np.ndarray
    observables: list[str]
    crest_levels: np.ndarray = field(repr=False)
    friction_values: np.ndarray = field(repr=False)

    @property
    def n_hpoints(self) -> int:
        """Number of h-points (level points)."""
        return len(self.hp_label)

    @property
    def n_links(self) -> int:
        """Number of links (discharge points)."""
        return len(self.link_label)


def compile_network(network: Network, settings: EngineSettings) -> CompiledNetwork:
    """Discretise a validated network and flatten it for the kernels.

    Parameters
    ----------
    network
        The validated network.
    settings
        Engine settings (structure length, minimum storage area).

    Returns
    -------
    CompiledNetwork
        Arrays and index maps; independent of parameter values and forcing.
    """
    profiles = {p.id: i for i, p in enumerate(network.profiles)}
    zw = [zw_of(p) for p in network.profiles]
    node_index = {n.id: i for i, n in enumerate(network.nodes)}
    hp_label = [f"node:{n.id}" for n in network.nodes]
    hp_branch = [""] * len(network.nodes)
    hp_chainage = [np.nan] * len(network.nodes)
    hp_xy = [(n.x if n.x is not None else np.nan, n.y if n.y is not None else np.nan) for n in network.nodes]
    contributions: dict[int, list[tuple[int, float, float]]] = defaultdict(list)

    on_branch: dict[str, list] = defaultdict(list)
    for s in [*network.weirs, *network.culverts, *network.pumps]:
        on_branch[s.branch].append(s)

    links: list[dict] = []
    branch_points: dict[str, tuple[np.ndarray, list[int]]] = {}
    for bi, br in enumerate(network.branches):
        try:
            segs = branch_layout(br, on_branch[br.id], settings.structure_length)
        except StructureOverlap as exc:  # validated at load; kept for networks built in code
            raise CaseError(f"structure {exc.structure.id!r} overlaps {exc.previous.id!r} on branch {br.id!r}; "
                            "see engine.structure_length") from None
        chain = np.array([segs[0].a] + [s.b for s in segs])
        ids = [node_index[br.from_node]]
        for c in chain[1:-1]:
            ids.append(len(hp_label))
            hp_label.append(f"{br.id}@{c:.1f}")
            hp_branch.append(br.id)
            hp_chainage.append(float(c))
            hp_xy.append(_xy_along(network, br, float(c)))
        ids.append(node_index[br.to_node])
        branch_points[br.id] = (chain, ids)
        seg_len = np.diff(chain)
        prof_at, bed_at = _section_lookup(br, profiles, chain)
        for j in range(chain.size):
            length = 0.5 * ((seg_len[j - 1] if j > 0 else 0.0) + (seg_len[j] if j < len(seg_len) else 0.0))
            contributions[ids[j]].append((prof_at[j], bed_at[j], length))
        for j, seg in enumerate(segs):
            links.append(
                dict(
                    k1=ids[j], k2=ids[j + 1], length=seg.b - seg.a, branch=bi, bid=br.id,
                    p1=prof_at[j], b1=bed_at[j], p2=prof_at[j + 1], b2=bed_at[j + 1],
                    chainage=0.5 * (seg.a + seg.b), structure=seg.structure,
                )
            )

    n_hp = len(hp_label)
    hp_bed = np.array([min(b for _, b, _ in contributions[i]) for i in range(n_hp)])
    hp_len = np.array([sum(length for _, _, length in contributions[i]) for i in range(n_hp)])
    # Node storage: a storage-only table with length 1 m.
    for node in network.nodes:
        i = node_index[node.id]
        if node.storage_table is not None:
            h, wf, wt, bottom = storage_zw(node.storage_table)
            zw.append((h, wf, wt))
            contributions[i].append((len(zw) - 1, bottom, 1.0))
        elif node.storage_area > 0:
            zw.append((np.array([0.0, 1.0]), np.zeros(2), np.full(2, node.storage_area)))
            contributions[i].append((len(zw) - 1, float(hp_bed[i]), 1.0))
    tables: ProfileTables = build_tables(zw)

    sc_ptr = np.zeros(n_hp + 1, dtype=np.int64)
    sc_prof, sc_bed, sc_len = [], [], []
    for i in range(n_hp):
        for p, b, length in contributions[i]:
            sc_prof.append(p)
            sc_bed.append(b)
            sc_len.append(length)
        sc_ptr[i + 1] = len(sc_prof)

    weirs = list(network.weirs)
    culverts = list(network.culverts)
    pumps = list(network.pumps)
    weir_pos = {w.id: i for i, w in enumerate(weirs)}
    culvert_pos = {c.id: i for i, c in enumerate(culverts)}
    pump_pos = {p.id: i for i, p in enumerate(pumps)}
    n_l = len(links)
    lk_type = np.zeros(n_l, dtype=np.int64)
    lk_sidx = np.full(n_l, -1, dtype=np.int64)
    structure_link: dict[str, int] = {}
    link_label = []
    for li, lk in enumerate(links):
        s = lk["structure"]
        if s is None:
            link_label.append(f"{lk['bid']}@{lk['chainage']:.1f}")
            continue
        structure_link[s.id] = li
        link_label.append(f"{type(s).__name__.lower()}:{s.id}")
        if isinstance(s, Weir):
            lk_type[li], lk_sidx[li] = LINK_WEIR, weir_pos[s.id]
        elif isinstance(s, Culvert):
            lk_type[li], lk_sidx[li] = LINK_CULVERT, culvert_pos[s.id]
        else:
            lk_type[li], lk_sidx[li] = LINK_PUMP, pump_pos[s.id]

    lk_k1 = np.array([lk["k1"] for lk in links], dtype=np.int64)
    lk_k2 = np.array([lk["k2"] for lk in links], dtype=np.int64)
    nl: dict[int, list[tuple[int, int]]] = defaultdict(list)
    for li in range(n_l):
        nl[int(lk_k1[li])].append((li, -1))
        nl[int(lk_k2[li])].append((li, +1))
    nl_ptr = np.zeros(n_hp + 1, dtype=np.int64)
    nl_link, nl_sign = [], []
    for i in range(n_hp):
        for li, sg in nl[i]:
            nl_link.append(li)
            nl_sign.append(sg)
        nl_ptr[i + 1] = len(nl_link)

    lk_nb = np.full((2, n_l), -2, dtype=np.int64)
    lk_ns = np.zeros((2, n_l), dtype=np.int64)
    for li in range(n_l):
        for end, k in enumerate((int(lk_k1[li]), int(lk_k2[li]))):
            others = [(lj, sg) for lj, sg in nl[k] if lj != li]
            if len(others) > 1:
                lk_nb[end, li] = -1
            elif len(others) == 1 and lk_type[others[0][0]] == LINK_CHANNEL:
                lk_nb[end, li], lk_ns[end, li] = others[0]

    edge_pairs = [(int(lk_k1[li]), int(lk_k2[li])) for li in range(n_l) if lk_type[li] != LINK_PUMP]
    solver = elimination_order(n_hp, edge_pairs)
    lk_edge = np.full(n_l, -1, dtype=np.int64)
    for li in range(n_l):
        if lk_type[li] != LINK_PUMP:
            lk_edge[li] = solver.edge_of[_key(int(lk_k1[li]), int(lk_k2[li]))]

    # Boundaries and laterals; forcing columns in order boundaries then laterals.
    forcing_keys: list[str] = []
    forcing_is_level: list[bool] = []
    b_hp, b_type, b_col, b_rptr, b_rlev, b_rq = [], [], [], [0], [], []
    type_code = {"discharge": BOUNDARY_DISCHARGE, "level": BOUNDARY_LEVEL, "rating": BOUNDARY_RATING}
    for bd in network.boundaries:
        b_hp.append(node_index[bd.node])
        b_type.append(type_code[bd.type])
        if bd.type == "rating":
            b_col.append(-1)
            b_rlev.extend(bd.rating.levels)
            b_rq.extend(bd.rating.discharges)
        else:
            b_col.append(len(forcing_keys))
            forcing_keys.append(f"boundary:{bd.id}")
            forcing_is_level.append(bd.type == "level")
        b_rptr.append(len(b_rlev))
    level_points = np.array([hp for hp, t in zip(b_hp, b_type, strict=True) if t == BOUNDARY_LEVEL], dtype=np.int64)
    lat_hp, lat_col = [], []
    for lat in network.laterals:
        if lat.node is not None:
            lat_hp.append(node_index[lat.node])
        else:
            chain, ids = branch_points[lat.branch]
            lat_hp.append(ids[int(np.argmin(np.abs(chain - lat.chainage)))])
        lat_col.append(len(forcing_keys))
        forcing_keys.append(f"lateral:{lat.id}")
        forcing_is_level.append(False)

    ob_type, ob_i1, ob_i2, ob_w, observables = _observables(network, links, structure_link, branch_points)

    branch_ids = [b.id for b in network.branches]
    fr_type = np.array(
        [FRICTION_CODES[(b.friction or network.friction).type] for b in network.branches], dtype=np.int64
    )
    friction_values = np.array([(b.friction or network.friction).value for b in network.branches], dtype=float)

    lk_fric = np.array([lk["branch"] for lk in links], dtype=np.int64)
    lk_ftype = fr_type[lk_fric]
    mo_runs, mo_other = momentum_runs(lk_type, lk_k1, lk_k2, lk_nb, lk_ns, lk_ftype, np.asarray(lat_hp, dtype=np.int64))
    arrays = NetArrays(
        hp_bed=hp_bed,
        hp_amin=np.full(n_hp, settings.min_storage_area),
        hp_ilen=np.divide(1.0, hp_len, out=np.zeros(n_hp), where=hp_len > 0),
        sc_ptr=sc_ptr,
        sc_prof=np.asarray(sc_prof, dtype=np.int64),
        sc_bed=np.asarray(sc_bed, dtype=float),
        sc_len=np.asarray(sc_len, dtype=float),
        nl_ptr=nl_ptr,
        nl_link=np.asarray(nl_link, dtype=np.int64),
        nl_sign=np.asarray(nl_sign, dtype=np.int64),
        lk_k1=lk_k1,
        lk_k2=lk_k2,
        lk_type=lk_type,
        lk_len=np.array([lk["length"] for lk in links], dtype=float),
        lk_ilen=1.0 / np.array([lk["length"] for lk in links], dtype=float),
        lk_p1=np.array([lk["p1"] for lk in links], dtype=np.int64),
        lk_b1=np.array([lk["b1"] for lk in links], dtype=float),
        lk_p2=np.array([lk["p2"] for lk in links], dtype=np.int64),
        lk_b2=np.array([lk["b2"] for lk in links], dtype=float),
        lk_fric=lk_fric,
        lk_sidx=lk_sidx,
        lk_edge=lk_edge,
        lk_nb1=lk_nb[0].copy(),
        lk_ns1=lk_ns[0].copy(),
        lk_nb2=lk_nb[1].copy(),
        lk_ns2=lk_ns[1].copy(),
        lk_runs=link_runs(lk_k1, lk_k2, lk_edge, (lk_type == LINK_PUMP) | np.isin(lk_k1, level_points)
                          | np.isin(lk_k2, level_points)),
        lk_ftype=lk_ftype,
        mo_runs=mo_runs,
        mo_other=mo_other,
        tab_off=tables.off,
        tab_n=tables.n,
        tab_dd=tables.dd,
        tab_idd=1.0 / tables.dd,
        tab_af=tables.af,
        tab_pf=tables.pf,
        tab_at=tables.at,
        tab_wt=tables.wt,
        tab_wf_top=tables.wf_top,
        tab_wt_top=tables.wt_top,
        tab_top=tables.top,
        tab_flow=flow_records(tables),
        fr_type=fr_type,
        w_width=np.array([w.crest_width for w in weirs], dtype=float),
        w_cmu=np.array([w.discharge_coefficient * w.lateral_contraction for w in weirs], dtype=float),
        w_dir=np.array([DIRECTION_CODES[w.allowed_flow] for w in weirs], dtype=np.int64),
        c_shape=np.array([0 if c.shape == "rectangular" else 1 for c in culverts], dtype=np.int64),
        c_width=np.array([c.width if c.shape == "rectangular" else c.diameter for c in culverts], dtype=float),
        c_height=np.array([c.opening_height for c in culverts], dtype=float),
        c_invert=np.array([c.invert_level for c in culverts], dtype=float),
        c_length=np.array([c.length for c in culverts], dtype=float),
        c_xin=np.array([c.inlet_loss for c in culverts], dtype=float),
        c_xout=np.array([c.outlet_loss for c in culverts], dtype=float),
        c_ftype=np.array([FRICTION_CODES[c.friction.type] for c in culverts], dtype=np.int64),
        c_fval=np.array([c.friction.value for c in culverts], dtype=float),
        c_dir=np.array([DIRECTION_CODES[c.allowed_flow] for c in culverts], dtype=np.int64),
        p_cap=np.array([p.capacity for p in pumps], dtype=float),
        p_on=np.array([p.start_level for p in pumps], dtype=float),
        p_off=np.array([p.stop_level for p in pumps], dtype=float),
        p_sign=np.array([1.0 if p.direction == "positive" else -1.0 for p in pumps], dtype=float),
        b_hp=np.asarray(b_hp, dtype=np.int64),
        b_type=np.asarray(b_type, dtype=np.int64),
        b_col=np.asarray(b_col, dtype=np.int64),
        b_rptr=np.asarray(b_rptr, dtype=np.int64),
        b_rlev=np.asarray(b_rlev, dtype=float),
        b_rq=np.asarray(b_rq, dtype=float),
        lat_hp=np.asarray(lat_hp, dtype=np.int64),
        lat_col=np.asarray(lat_col, dtype=np.int64),
        sv_order=solver.order,
        sv_cptr=solver.cptr,
        sv_cedge=solver.cedge,
        sv_cother=solver.cother,
        sv_uptr=solver.uptr,
        sv_ue1=solver.ue1,
        sv_ue2=solver.ue2,
        sv_utgt=solver.utgt,
        sv_nedge=solver.n_edges,
        sv_sched=solver_schedule(solver),
        ob_type=ob_type,
        ob_i1=ob_i1,
        ob_i2=ob_i2,
        ob_w=ob_w,
    )
    return CompiledNetwork(
        arrays=arrays,
        hp_label=hp_label,
        hp_branch=hp_branch,
        hp_chainage=np.asarray(hp_chainage, dtype=float),
        hp_xy=np.asarray(hp_xy, dtype=float),
        link_label=link_label,
        link_branch=[lk["bid"] for lk in links],
        link_chainage=np.array([lk["chainage"] for lk in links], dtype=float),
        structure_link=structure_link,
        weir_ids=[w.id for w in weirs],
        branch_ids=branch_ids,
        branch_inherits=[b.id for b in network.branches if b.friction is None],
        boundary_ids=[b.id for b in network.boundaries],
        lateral_ids=[lat.id for lat in network.laterals],
        forcing_keys=forcing_keys,
        forcing_is_level=np.asarray(forcing_is_level, dtype=bool),
        observables=observables,
        crest_levels=np.array([w.crest_level for w in weirs], dtype=float),
        friction_values=friction_values,
    )


def _section_lookup(branch: Branch, profiles: dict[str, int], chain: np.ndarray) -> tuple[list[int], list[float]]:
    """Profile index (of the nearest cross-section) and bed level (m AD, linear) at each chainage."""
    cs_ch = np.array([cs.chainage for cs in branch.cross_sections])
    cs_bed = np.array([cs.bed_level for cs in branch.cross_sections])
    cs_prof = np.array([profiles[cs.profile] for cs in branch.cross_sections])
    right = np.clip(np.searchsorted(cs_ch, chain), 0, cs_ch.size - 1)
    left = np.clip(right - 1, 0, cs_ch.size - 1)
    nearest = np.where(np.abs(chain - cs_ch[left]) <= np.abs(cs_ch[right] - chain), left, right)
    return [int(p) for p in cs_prof[nearest]], [float(b) for b in np.interp(chain, cs_ch, cs_bed)]


def _xy_along(network: Network, branch: Branch, chainage: float) -> tuple[float, float]:
    """Map position of a chainage, along the branch polyline or the straight line between its nodes."""
    if branch.geometry:
        pts = np.asarray(branch.geometry, dtype=float)
    else:
        a = next(n for n in network.nodes if n.id == branch.from_node)
        b = next(n for n in network.nodes if n.id == branch.to_node)
        if None in (a.x, a.y, b.x, b.y):
            return (np.nan, np.nan)
        pts = np.array([[a.x, a.y], [b.x, b.y]], dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    frac = chainage / branch.length * s[-1]
    return (float(np.interp(frac, s, pts[:, 0])), float(np.interp(frac, s, pts[:, 1])))


def _observables(network: Network, links: list[dict], structure_link: dict[str, int], branch_points: dict):
    ob_type, ob_i1, ob_i2, ob_w, names = [], [], [], [], []
    for st in network.stations:
        for name in st.observables:
            quantity = name.rsplit(".", 1)[1]
            if st.structure is not None:
                li = structure_link[st.structure]
                if quantity == "Q":
                    ob_type.append(OBS_FLUX)
                    ob_i1.append(li)
                    ob_i2.append(li)
                    ob_w.append(1.0)
                else:
                    k = links[li]["k1"] if quantity == "h_up" else links[li]["k2"]
                    ob_type.append(OBS_LEVEL)
                    ob_i1.append(k)
                    ob_i2.append(k)
                    ob_w.append(1.0)
            else:
                chain, ids = branch_points[st.branch]
                j = int(np.clip(np.searchsorted(chain, st.chainage, side="right") - 1, 0, len(chain) - 2))
                if quantity == "h":
                    frac = (st.chainage - chain[j]) / (chain[j + 1] - chain[j])
                    ob_type.append(OBS_LEVEL)
                    ob_i1.append(ids[j])
                    ob_i2.append(ids[j + 1])
                    ob_w.append(1.0 - frac)
                else:
                    li = _link_at(links, st.branch, st.chainage)
                    ob_type.append(OBS_FLUX)
                    ob_i1.append(li)
                    ob_i2.append(li)
                    ob_w.append(1.0)
            names.append(name)
    return (
        np.asarray(ob_type, dtype=np.int64),
        np.asarray(ob_i1, dtype=np.int64),
        np.asarray(ob_i2, dtype=np.int64),
        np.asarray(ob_w, dtype=float),
        names,
    )


def _link_at(links: list[dict], branch_id: str, chainage: float) -> int:
    best, best_d = -1, np.inf
    for li, lk in enumerate(links):
        if lk["bid"] != branch_id:
            continue
        half = 0.5 * lk["length"]
        d = abs(lk["chainage"] - chainage)
        if d <= half + 1e-9 and d < best_d:
            best, best_d = li, d
    return best


# -- symbolic LDLᵀ ------------------------------------------------------------------------------


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
    heap = [(len(adj[i]), i) for i in range(n)]
    heapq.heapify(heap)
    eliminated = np.zeros(n, dtype=bool)
    order: list[int] = []
    later: list[list[int]] = []
    while heap:
        deg, i = heapq.heappop(heap)
        if eliminated[i] or deg != len(adj[i]):
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
        for a in nbrs:
            heapq.heappush(heap, (len(adj[a]), a))
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


#: Values per elimination step and lane in :func:`solver_schedule`.
SCHED_WIDTH = 8


def solver_schedule(sym: SymbolicLDL) -> np.ndarray:
    """The symbolic factorisation as a two-lane schedule for :func:`~rivercal.engine.kernels.solver.ldl_solve_packed`.

    Along a branch every elimination depends on the previous one, so the solve is bound by the latency of
    that chain; two independent eliminations per step let the processor overlap two chains. A step holds
    two lanes of ``SCHED_WIDTH`` unsigned integers: the point eliminated (``n``: the lane is empty), the
    number m of its later neighbours, their edges and points when m is 1 or 2 (``k, m, e1, o1, e2, o2``),
    then the edge between the two (m = 2) or the elimination position in ``sym`` (m > 2, read from the
    CSR arrays; such a step has one lane), and which later point the lane carries to its next step
    (0: o1, 1: o2, 2: none).

    Two eliminations are paired only when neither touches an entry (pivot, later point, edge, fill
    target) that the other touches, and every entry is updated by the same eliminations in the same
    order as in ``sym.order``: the result is bit-identical to the one-lane solve. The steps follow a
    list schedule by longest remaining chain, keeping each chain in its lane so that the value it
    updates stays in a register (the "carry").

    Parameters
    ----------
    sym
        The symbolic factorisation of :func:`elimination_order`.

    Returns
    -------
    numpy.ndarray
        ``uint64`` array of ``2 * SCHED_WIDTH`` entries per step.
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
    carried = [n, n]  # the point each lane carries into its next step
    while ready:
        first = heapq.heappop(ready)[1]
        take = [first]
        if width[first] <= 2 and ready and width[ready[0][1]] <= 2:
            take.append(heapq.heappop(ready)[1])
        lanes: list[int | None] = [None, None]
        for p in take:  # an elimination of a carried point goes to the lane that carries it
            if int(sym.order[p]) in carried:
                lanes[carried.index(int(sym.order[p]))] = p
        for p in take:
            if p not in lanes:
                lanes[lanes.index(None)] = p
        step = []
        for lane, p in enumerate(lanes):
            rec = np.zeros(SCHED_WIDTH, dtype=np.uint64)
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
    return np.array(steps, dtype=np.uint64).ravel()


#: Columns of a row of ``lk_runs`` (:func:`link_runs`).
RUN_LINK, RUN_COUNT, RUN_K1, RUN_K2, RUN_EDGE, RUN_GENERAL = range(6)


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
    return np.array(rows, dtype=np.uint64).reshape(-1, 6)


def momentum_runs(lk_type: np.ndarray, lk_k1: np.ndarray, lk_k2: np.ndarray, lk_nb: np.ndarray,
                  lk_ns: np.ndarray, lk_ftype: np.ndarray, lateral_points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The channel links whose momentum terms a branch-free, contiguous loop can compute, as runs; the others.

    Inside a branch a channel link ``l`` joins consecutive points (k2 = k1 + 1) and its upwind neighbour is
    the next channel link along the branch on either side: link ``l - 1`` ending at k1, link ``l + 1``
    starting at k2. For such *simple* links the momentum pass reads the levels, the neighbours' velocities
    and fluxes contiguously (:func:`rivercal.engine.kernels.timeloop.channel_coefficients`). A channel link
    next to a junction, a structure, a branch end or a lateral, or with Chézy friction (whose hydraulic
    radius costs a division that the others do not need), is one of the others.

    Parameters
    ----------
    lk_type, lk_k1, lk_k2
        Per link: its type and its two h-points.
    lk_nb, lk_ns
        Per end (rows) and link: the one other channel link at that end (-1 junction, -2 none or a
        structure) and +1 if it ends there, -1 if it starts there.
    lk_ftype
        Per link: its friction type (``FRICTION_CODES``).
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
    simple = ((lk_type == LINK_CHANNEL) & (lk_k2 == lk_k1 + 1) & (lk_nb[0] == index - 1) & (lk_ns[0] == 1)
              & (lk_nb[1] == index + 1) & (lk_ns[1] == -1) & (lk_ftype != FRICTION_CODES["chezy"])
              & ~np.isin(lk_k1, lateral_points) & ~np.isin(lk_k2, lateral_points))
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
    return np.array(rows, dtype=np.uint64).reshape(-1, 3), other.astype(np.uint64)


#: Values per table cell in ``tab_flow``: af, its increment, pf, its increment, r43, its increment, 2 unused.
FLOW_WIDTH = 8


def _aligned_empty(n: int, align: int = 64) -> np.ndarray:
    """A float64 array of ``n`` zeros whose data starts on an ``align``-byte boundary (a cache line)."""
    raw = np.zeros(n + align // 8)
    start = (-raw.ctypes.data % align) // 8
    return raw[start : start + n]


def flow_records(tables: ProfileTables) -> np.ndarray:
    """The flow tables as one cache-line record per cell: a look-up reads one line, not six values in three arrays.

    The increments are the differences the interpolation takes (``af[k + 1] - af[k]``, computed the same way), so
    the interpolated values are bit-identical; the last cell of each table, never interpolated from, has none.
    """
    n = tables.af.size
    rec = _aligned_empty(n * FLOW_WIDTH).reshape(n, FLOW_WIDTH)
    last = np.zeros(n, dtype=bool)
    last[tables.off + tables.n - 1] = True
    for col, values in enumerate((tables.af, tables.pf, tables.r43)):
        rec[:, 2 * col] = values
        inc = np.zeros(n)
        inc[:-1] = values[1:] - values[:-1]
        inc[last] = 0.0
        rec[:, 2 * col + 1] = inc
    return rec.ravel()
