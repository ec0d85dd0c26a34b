"""Network → flat arrays for the kernels: the packing of the grid, the geometry tables and the solver plan.

This runs once per network (not per run, never per time step). :func:`compile_network` takes the grid
of :func:`rivercal.network.grid.layout_grid`, tabulates the cross-sections and storage
(:mod:`rivercal.engine.geometry`), joins each point to its links and computes the solver plan
(:mod:`rivercal.engine.plan`), and places the structures, boundaries, laterals and stations, writing the
integer codes of :mod:`rivercal.engine.kernels.codes`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from rivercal.case.schema import EngineSettings
from rivercal.engine.geometry import ProfileTables, build_tables, flow_records, storage_zw, zw_of
from rivercal.engine.kernels.codes import (
    BOUNDARY_DISCHARGE,
    BOUNDARY_LEVEL,
    BOUNDARY_RATING,
    CULVERT_CIRCULAR,
    CULVERT_RECTANGULAR,
    FLOW_BOTH,
    FLOW_NEGATIVE,
    FLOW_NONE,
    FLOW_POSITIVE,
    FRICTION_CHEZY,
    FRICTION_MANNING,
    FRICTION_STRICKLER,
    LINK_CHANNEL,
    LINK_CULVERT,
    LINK_PUMP,
    LINK_WEIR,
    OBS_FLUX,
    OBS_LEVEL,
)
from rivercal.engine.plan import connectivity, solver_plan
from rivercal.network import Culvert, Network, Pump, Weir
from rivercal.network.grid import Grid, layout_grid

__all__ = [
    "DIRECTION_CODES",
    "FRICTION_CODES",
    "CompiledNetwork",
    "NetArrays",
    "compile_network",
]

#: Friction type names of the case → codes of the kernel arrays.
FRICTION_CODES = {"strickler": FRICTION_STRICKLER, "manning": FRICTION_MANNING, "chezy": FRICTION_CHEZY}
#: ``allowed_flow`` of a structure → codes of the kernel arrays.
DIRECTION_CODES = {"both": FLOW_BOTH, "positive": FLOW_POSITIVE, "negative": FLOW_NEGATIVE, "none": FLOW_NONE}
_BOUNDARY_CODES = {"discharge": BOUNDARY_DISCHARGE, "level": BOUNDARY_LEVEL, "rating": BOUNDARY_RATING}


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
    lk_nb1: np.ndarray  # the one other channel link at k1 (NB_JUNCTION: a junction, NB_NONE: none or a structure)
    lk_ns1: np.ndarray  # +1 if that link ends at k1, -1 if it starts there
    lk_nb2: np.ndarray  # same at k2
    lk_ns2: np.ndarray
    lk_runs: np.ndarray  # the links as runs along which k1, k2 and the edge step by one (uint64, plan.link_runs)
    lk_ftype: np.ndarray  # friction type of the link's group (FRICTION_CODES)
    mo_runs: np.ndarray  # runs of channel links whose momentum terms vectorise (uint64, plan.momentum_runs)
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
    sv_cptr: np.ndarray
    sv_cedge: np.ndarray
    sv_cother: np.ndarray
    sv_uptr: np.ndarray
    sv_ue1: np.ndarray
    sv_ue2: np.ndarray
    sv_utgt: np.ndarray
    sv_nedge: int
    sv_sched: np.ndarray  # the same as a two-lane schedule for ldl_solve_packed (uint64, plan.solver_schedule)
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

    Raises
    ------
    rivercal.network.grid.StructureOverlap
        (a :class:`~rivercal.errors.CaseError`) when two structures are too close for the structure
        length; a case checks this at load.
    """
    grid = layout_grid(network, settings.structure_length)
    n_hp = grid.n_points
    storage = _storage(network, grid, settings.min_storage_area)
    weirs, culverts, pumps = list(network.weirs), list(network.culverts), list(network.pumps)
    lk_type, lk_sidx = _structure_links(grid, weirs, culverts, pumps)
    lk_k1, lk_k2 = grid.link_k1, grid.link_k2
    nl_ptr, nl_link, nl_sign, lk_nb, lk_ns = connectivity(n_hp, lk_k1, lk_k2, lk_type)
    forcing, forcing_keys, forcing_is_level = _forcing(network, grid)
    ob_type, ob_i1, ob_i2, ob_w, observables = _observables(network, grid)
    fr_type = np.array(
        [FRICTION_CODES[(b.friction or network.friction).type] for b in network.branches], dtype=np.int64
    )
    friction_values = np.array([(b.friction or network.friction).value for b in network.branches], dtype=float)
    lk_ftype = fr_type[grid.link_branch]
    level_points = forcing["b_hp"][forcing["b_type"] == BOUNDARY_LEVEL]
    plan = solver_plan(n_hp, lk_type, lk_k1, lk_k2, lk_nb, lk_ns, lk_ftype, level_points, forcing["lat_hp"])
    arrays = NetArrays(
        **storage,
        nl_ptr=nl_ptr,
        nl_link=nl_link,
        nl_sign=nl_sign,
        lk_k1=lk_k1,
        lk_k2=lk_k2,
        lk_type=lk_type,
        lk_len=grid.link_length,
        lk_ilen=1.0 / grid.link_length,
        lk_p1=grid.link_p1,
        lk_b1=grid.link_b1,
        lk_p2=grid.link_p2,
        lk_b2=grid.link_b2,
        lk_fric=grid.link_branch,
        lk_sidx=lk_sidx,
        lk_edge=plan.link_edge,
        lk_nb1=lk_nb[0].copy(),
        lk_ns1=lk_ns[0].copy(),
        lk_nb2=lk_nb[1].copy(),
        lk_ns2=lk_ns[1].copy(),
        lk_runs=plan.link_runs,
        lk_ftype=lk_ftype,
        mo_runs=plan.momentum_runs,
        mo_other=plan.momentum_other,
        fr_type=fr_type,
        **_structure_arrays(weirs, culverts, pumps),
        **forcing,
        sv_cptr=plan.symbolic.cptr,
        sv_cedge=plan.symbolic.cedge,
        sv_cother=plan.symbolic.cother,
        sv_uptr=plan.symbolic.uptr,
        sv_ue1=plan.symbolic.ue1,
        sv_ue2=plan.symbolic.ue2,
        sv_utgt=plan.symbolic.utgt,
        sv_nedge=plan.symbolic.n_edges,
        sv_sched=plan.schedule,
        ob_type=ob_type,
        ob_i1=ob_i1,
        ob_i2=ob_i2,
        ob_w=ob_w,
    )
    return CompiledNetwork(
        arrays=arrays,
        hp_label=grid.hp_label,
        hp_branch=grid.hp_branch,
        hp_chainage=grid.hp_chainage,
        hp_xy=grid.hp_xy,
        link_label=grid.link_label,
        link_branch=grid.link_branch_id,
        link_chainage=grid.link_chainage,
        structure_link=grid.structure_link,
        weir_ids=[w.id for w in weirs],
        branch_ids=[b.id for b in network.branches],
        branch_inherits=[b.id for b in network.branches if b.friction is None],
        boundary_ids=[b.id for b in network.boundaries],
        lateral_ids=[lat.id for lat in network.laterals],
        forcing_keys=forcing_keys,
        forcing_is_level=np.asarray(forcing_is_level, dtype=bool),
        observables=observables,
        crest_levels=np.array([w.crest_level for w in weirs], dtype=float),
        friction_values=friction_values,
    )


def _storage(network: Network, grid: Grid, min_storage_area: float) -> dict[str, np.ndarray]:
    """The ``hp_*``, ``sc_*`` and ``tab_*`` arrays: each h-point's storage and the tables of every profile and node.

    A point's storage is the sum of its contributions: the half-segments of the channel it represents,
    and its node storage (a table of length 1 m), plus the minimum storage area ``min_storage_area`` (m²).
    """
    zw = [zw_of(p) for p in network.profiles]
    contributions = [list(sections) for sections in grid.sections]
    n_hp = len(contributions)
    hp_bed = np.array([min(b for _, b, _ in c) for c in contributions])
    hp_len = np.array([sum(length for _, _, length in c) for c in contributions])
    for node in network.nodes:
        i = grid.node_index[node.id]
        if node.storage_table is not None:
            h, wf, wt, bottom = storage_zw(node.storage_table)
            zw.append((h, wf, wt))
            contributions[i].append((len(zw) - 1, bottom, 1.0))
        elif node.storage_area > 0:
            zw.append((np.array([0.0, 1.0]), np.zeros(2), np.full(2, node.storage_area)))
            contributions[i].append((len(zw) - 1, float(hp_bed[i]), 1.0))
    tables: ProfileTables = build_tables(zw)
    sc_ptr = np.zeros(n_hp + 1, dtype=np.int64)
    sc_ptr[1:] = np.cumsum([len(c) for c in contributions])
    flat = [entry for c in contributions for entry in c]
    return dict(
        hp_bed=hp_bed,
        hp_amin=np.full(n_hp, min_storage_area),
        hp_ilen=np.divide(1.0, hp_len, out=np.zeros(n_hp), where=hp_len > 0),
        sc_ptr=sc_ptr,
        sc_prof=np.array([p for p, _, _ in flat], dtype=np.int64),
        sc_bed=np.array([b for _, b, _ in flat], dtype=float),
        sc_len=np.array([length for _, _, length in flat], dtype=float),
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
    )


def _structure_arrays(weirs: list[Weir], culverts: list[Culvert], pumps: list[Pump]) -> dict[str, np.ndarray]:
    """The ``w_*``, ``c_*`` and ``p_*`` arrays (one entry per weir, culvert, pump)."""
    return dict(
        w_width=np.array([w.crest_width for w in weirs], dtype=float),
        w_cmu=np.array([w.discharge_coefficient * w.lateral_contraction for w in weirs], dtype=float),
        w_dir=np.array([DIRECTION_CODES[w.allowed_flow] for w in weirs], dtype=np.int64),
        c_shape=np.array([CULVERT_RECTANGULAR if c.shape == "rectangular" else CULVERT_CIRCULAR for c in culverts],
                         dtype=np.int64),
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
    )


def _forcing(network: Network, grid: Grid) -> tuple[dict[str, np.ndarray], list[str], list[bool]]:
    """The ``b_*`` and ``lat_*`` arrays, and the forcing columns: boundaries first, then laterals.

    Returns the arrays, the key of each forcing column (``boundary:<id>``, ``lateral:<id>``) and whether
    it holds a level (m AD) rather than a discharge (m³/s). A rating boundary has no column (-1).
    """
    keys: list[str] = []
    is_level: list[bool] = []
    b_hp, b_type, b_col, b_rptr, b_rlev, b_rq = [], [], [], [0], [], []
    for bd in network.boundaries:
        b_hp.append(grid.node_index[bd.node])
        b_type.append(_BOUNDARY_CODES[bd.type])
        if bd.type == "rating":
            b_col.append(-1)
            b_rlev.extend(bd.rating.levels)
            b_rq.extend(bd.rating.discharges)
        else:
            b_col.append(len(keys))
            keys.append(f"boundary:{bd.id}")
            is_level.append(bd.type == "level")
        b_rptr.append(len(b_rlev))
    lat_hp, lat_col = [], []
    for lat in network.laterals:
        on_node = lat.node is not None
        lat_hp.append(grid.node_index[lat.node] if on_node else grid.nearest_point(lat.branch, lat.chainage))
        lat_col.append(len(keys))
        keys.append(f"lateral:{lat.id}")
        is_level.append(False)
    arrays = dict(
        b_hp=np.asarray(b_hp, dtype=np.int64),
        b_type=np.asarray(b_type, dtype=np.int64),
        b_col=np.asarray(b_col, dtype=np.int64),
        b_rptr=np.asarray(b_rptr, dtype=np.int64),
        b_rlev=np.asarray(b_rlev, dtype=float),
        b_rq=np.asarray(b_rq, dtype=float),
        lat_hp=np.asarray(lat_hp, dtype=np.int64),
        lat_col=np.asarray(lat_col, dtype=np.int64),
    )
    return arrays, keys, is_level


def _structure_links(grid: Grid, weirs: list, culverts: list, pumps: list) -> tuple[np.ndarray, np.ndarray]:
    """Per link: its type code and its index in the weir, culvert or pump arrays (-1 for a channel)."""
    position = {s.id: i for group in (weirs, culverts, pumps) for i, s in enumerate(group)}
    lk_type = np.full(grid.n_links, LINK_CHANNEL, dtype=np.int64)
    lk_sidx = np.full(grid.n_links, -1, dtype=np.int64)
    for li, s in enumerate(grid.link_structure):
        if s is not None:
            lk_type[li] = LINK_WEIR if isinstance(s, Weir) else LINK_CULVERT if isinstance(s, Culvert) else LINK_PUMP
            lk_sidx[li] = position[s.id]
    return lk_type, lk_sidx


def _observables(network: Network, grid: Grid) -> tuple:
    """Per observable of the stations: kind (``OBS_*``), two indices and the weight of the first; the names."""
    ob_type, ob_i1, ob_i2, ob_w, names = [], [], [], [], []

    def add(kind: int, i1: int, i2: int, w: float) -> None:
        ob_type.append(kind)
        ob_i1.append(i1)
        ob_i2.append(i2)
        ob_w.append(w)

    for st in network.stations:
        for name in st.observables:
            quantity = name.rsplit(".", 1)[1]
            if st.structure is not None:
                li = grid.structure_link[st.structure]
                if quantity == "Q":
                    add(OBS_FLUX, li, li, 1.0)
                else:
                    k = int(grid.link_k1[li] if quantity == "h_up" else grid.link_k2[li])
                    add(OBS_LEVEL, k, k, 1.0)
            elif quantity == "h":
                add(OBS_LEVEL, *grid.interval(st.branch, st.chainage))
            else:
                li = grid.link_at(st.branch, st.chainage)
                add(OBS_FLUX, li, li, 1.0)
            names.append(name)
    return (
        np.asarray(ob_type, dtype=np.int64),
        np.asarray(ob_i1, dtype=np.int64),
        np.asarray(ob_i2, dtype=np.int64),
        np.asarray(ob_w, dtype=float),
        names,
    )
