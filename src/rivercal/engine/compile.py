"""Network → flat arrays for the kernels: the packing of the grid, the geometry tables and the solver plan.

This runs once per network (not per run, never per time step). :func:`compile_network` takes the grid
of :func:`rivercal.network.grid.layout_grid`, tabulates the cross-sections and storage
(:mod:`rivercal.engine.geometry`), joins each point to its links and computes the solver plan
(:mod:`rivercal.engine.plan`), and places the structures, boundaries, laterals and stations, writing the
integer codes of :mod:`rivercal.engine.kernels.codes`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from rivercal.case.schema import EngineSettings
from rivercal.engine.channels import FRICTION_CODES, channel_geometry
from rivercal.engine.kernels.codes import (
    BOUNDARY_DISCHARGE,
    BOUNDARY_LEVEL,
    BOUNDARY_RATING,
    C_EXPAND,
    C_INVERT2,
    C_PROF,
    C_WIDTH,
    CULVERT_CIRCULAR,
    CULVERT_PROFILE,
    CULVERT_RECTANGULAR,
    FLOW_BOTH,
    FLOW_NEGATIVE,
    FLOW_NONE,
    FLOW_POSITIVE,
    LINK_CHANNEL,
    LINK_CULVERT,
    LINK_ORIFICE,
    LINK_PUMP,
    LINK_UNIVERSAL_WEIR,
    LINK_WEIR,
    NB_OUTFALL,
    O_WIDTH,
    OBS_FLUX,
    OBS_LEVEL,
    U_WIDTH,
)
from rivercal.engine.kernels.structures import G
from rivercal.engine.plan import connectivity, drop_links, solver_plan
from rivercal.errors import CaseError
from rivercal.network import Bridge, CircularProfile, Culvert, Network, Orifice, Pump, UniversalWeir, Weir
from rivercal.network.grid import Grid, layout_grid

__all__ = [
    "DIRECTION_CODES",
    "FRICTION_CODES",
    "CompiledNetwork",
    "DikeArrays",
    "NetArrays",
    "StructureArrays",
    "compile_network",
    "own_friction_slots",
]

#: ``allowed_flow`` of a structure → codes of the kernel arrays.
DIRECTION_CODES = {"both": FLOW_BOTH, "positive": FLOW_POSITIVE, "negative": FLOW_NEGATIVE, "none": FLOW_NONE}
_BOUNDARY_CODES = {"discharge": BOUNDARY_DISCHARGE, "level": BOUNDARY_LEVEL, "rating": BOUNDARY_RATING,
                   "critical": BOUNDARY_RATING}
#: Levels of the table of a critical boundary (:func:`critical_rating`).
CRITICAL_LEVELS = 401
#: Integer arrays of :class:`NetArrays` that the time loop reads every step, stored narrower than numpy's int64
#: (:func:`_narrow`): codes and signs in one byte, point, link, edge and table indices in four.
_BYTE_CODES = ("lk_type", "lk_ftype", "lk_ns1", "lk_ns2", "nl_sign")
_INDICES = ("lk_k1", "lk_k2", "lk_p1", "lk_p2", "lk_fric", "lk_sidx", "lk_edge", "lk_nb1", "lk_nb2", "nl_ptr",
            "nl_link", "sc_ptr", "sc_prof", "sv_cptr", "sv_cedge", "sv_cother", "sv_uptr", "sv_ue1", "sv_ue2",
            "sv_utgt")


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
    lk_fric: np.ndarray  # friction slot (channels.Channels: branches, then friction groups)
    lk_sidx: np.ndarray  # index in the weir/culvert/pump arrays
    lk_edge: np.ndarray  # solver edge, -1 for pumps
    lk_nb1: np.ndarray  # the one other channel link at k1 (NB_JUNCTION: a junction, NB_NONE: none or a structure,
    #                     NB_OUTFALL: k1 is a free outfall)
    lk_ns1: np.ndarray  # +1 if that link ends at k1, -1 if it starts there
    lk_nb2: np.ndarray  # same at k2
    lk_ns2: np.ndarray
    lk_runs: np.ndarray  # the links as runs along which k1, k2 and the edge step by one (uint64, plan.link_runs)
    lk_ftype: np.ndarray  # friction type of the link's group (FRICTION_CODES)
    mo_runs: np.ndarray  # runs of channel links whose momentum terms vectorise (uint64, plan.momentum_runs)
    mo_other: np.ndarray  # the other channel links (uint64)
    dl_link: np.ndarray  # channel links whose bed ends above the bed of an end point (a drop: kernels.overfall)
    of_link: np.ndarray  # channel links that reach a free outfall (a critical boundary: kernels.outfall)
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
    # friction slots
    fr_type: np.ndarray
    # weirs
    w_width: np.ndarray  # m
    w_cmu: np.ndarray  # c_e * c_w
    w_dir: np.ndarray
    # culverts, then bridges (culverts of an open profile)
    c_shape: np.ndarray  # CULVERT_RECTANGULAR, CULVERT_CIRCULAR or CULVERT_PROFILE
    c_width: np.ndarray  # m (diameter for circular)
    c_height: np.ndarray  # m (the crown of a profile; 1e10 for an open one)
    c_invert: np.ndarray  # m AD, at the k1 end
    c_length: np.ndarray  # m
    c_xin: np.ndarray  # entrance and bend losses
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
    sv_sched: np.ndarray  # the same as a four-lane schedule for ldl_solve_packed (uint32, plan.solver_schedule)
    # observables
    ob_type: np.ndarray
    ob_i1: np.ndarray
    ob_i2: np.ndarray
    ob_w: np.ndarray


class StructureArrays(NamedTuple):
    """What the structure kernels know beyond :class:`NetArrays`: the D-HYDRO structures and the settings series.

    Kept apart from :class:`NetArrays`, which nearly every kernel receives: a kernel call passes a named
    tuple field by field, and five more arrays in it slowed a synthetic week by a third (measured).
    ``ogate`` is scratch: the orifice gates of the current step (m AD).
    """

    c_extra: np.ndarray  # per culvert and bridge the C_* columns: invert at the k2 end (m AD), expansion, barrel table
    o_par: np.ndarray  # per orifice the O_* columns: crest (m AD), width (m), gate (m AD), mu, direction, limits (m³/s)
    u_par: np.ndarray  # per universal weir the U_* columns: c_e, direction, first and end crest strip
    u_strip: np.ndarray  # per crest strip: width (m), crest (m AD)
    set_col: np.ndarray  # forcing column of each setting series (-1: constant): weirs', orifices' gates, pumps'
    links: np.ndarray  # the links of orifices, universal weirs and culverts or bridges with an extension
    ogate: np.ndarray
    pnom: np.ndarray  # the pumps' own capacities, m³/s (a capacity series writes NetArrays.p_cap each step)


class DikeArrays(NamedTuple):
    """The summer dikes' storage contributions whose curve depends on the way the level last went (hysteresis).

    Such a contribution stores with its rising curve (``rise``, the table of ``NetArrays.sc_prof`` as compiled)
    until the level at its point reaches ``full``, then with its falling curve (``alt``) until the level falls to
    ``base``. The time loop switches the table of the contribution in the ``sc_prof`` of the run
    (:func:`rivercal.engine.kernels.timeloop.switch_dikes`); the engine state holds which curve each one is on.
    Kept apart from :class:`NetArrays`, which nearly every kernel receives: only the time loop of a network with
    such dikes gets these.
    """

    sc: np.ndarray  # the contribution (index into sc_prof, sc_bed, sc_len)
    hp: np.ndarray  # its h-point
    rise: np.ndarray  # table of the rising curve
    alt: np.ndarray  # table of the falling curve
    full: np.ndarray  # m AD
    base: np.ndarray  # m AD


@dataclass(frozen=True)
class CompiledNetwork:
    """The flat kernel arrays plus the index maps that translate names to positions.

    Attributes
    ----------
    arrays
        Kernel input.
    structures
        Kernel input of the structure kernels (:class:`StructureArrays`).
    dikes
        The summer dikes whose storage changes curve (:class:`DikeArrays`; empty arrays without such dikes).
    hp_label, hp_branch, hp_chainage, hp_xy
        Per h-point: label, branch id ("" for nodes), chainage (m; nan for nodes), map position (m).
    link_label, link_branch, link_chainage
        Per link: label, branch id, chainage of its midpoint (m).
    structure_link
        Link index of each structure id.
    weir_ids, branch_ids
        Order of the weir array and of the first friction slots (one per branch).
    friction_slots
        Key of every friction slot: ``("branch", id)``, ``("group", id)``, ``("group", id, branch)``;
        ``friction_values`` holds their values.
    friction_mixed
        Friction groups that a profile names beside another group → that profile's id
        (:attr:`rivercal.engine.channels.Channels.mixed_groups`): not calibration targets.
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
    structures: StructureArrays
    dikes: DikeArrays
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
    friction_slots: list[tuple] = field(default_factory=list, repr=False)
    friction_mixed: dict[str, str] = field(default_factory=dict, repr=False)

    @property
    def n_hpoints(self) -> int:
        """Number of h-points (level points)."""
        return len(self.hp_label)

    @property
    def n_links(self) -> int:
        """Number of links (discharge points)."""
        return len(self.link_label)


def _narrow(arrays: NetArrays) -> NetArrays:
    """``arrays`` with the integer arrays the time loop reads every step in 1-byte codes and 4-byte indices.

    A board-size network's arrays do not fit in the processor's cache, and the time loop streams them from
    memory every step: narrower integers make that stream shorter (a week of the 38,652-point generated
    network: 16 % less time, the median of three runs each way, with bit-identical results; no change at 479
    points).
    """
    narrowed = {}
    for names, dtype in ((_BYTE_CODES, np.int8), (_INDICES, np.int32)):
        info = np.iinfo(dtype)
        for name in names:
            values = getattr(arrays, name)
            if values.size and (values.min() < info.min or values.max() > info.max):
                raise OverflowError(f"{name} holds values from {values.min()} to {values.max()}, outside the range "
                                    f"of the engine's {info.bits}-bit integers (a network of more than 2^31 points "
                                    f"or edges is too large for it)")
            narrowed[name] = values.astype(dtype)
    return arrays._replace(**narrowed)


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
    channels = channel_geometry(network, grid, settings.cross_sections, settings.min_storage_area)
    weirs, culverts, pumps = list(network.weirs), list(network.culverts), list(network.pumps)
    orifices, uweirs, bridges = list(network.orifices), list(network.universal_weirs), list(network.bridges)
    lk_type, lk_sidx = _structure_links(grid, weirs, culverts + bridges, pumps, orifices, uweirs)
    lk_k1, lk_k2 = grid.link_k1, grid.link_k2
    nl_ptr, nl_link, nl_sign, lk_nb, lk_ns = connectivity(n_hp, lk_k1, lk_k2, lk_type)
    for bd in network.boundaries:
        if bd.type == "critical":  # the channel link that reaches a free outfall (critical_rating checks it is one)
            point = grid.node_index[bd.node]
            for link in np.flatnonzero(((lk_k1 == point) | (lk_k2 == point)) & (lk_type == LINK_CHANNEL)):
                lk_nb[0 if lk_k1[link] == point else 1, link] = NB_OUTFALL
    forcing, forcing_keys, forcing_is_level = _forcing(network, grid, lambda i, bd: critical_rating(
        grid.node_index[bd.node], lk_k1, lk_k2, lk_type, channels.link_p1, channels.link_b1, channels.link_p2,
        channels.link_b2, channels.storage, what=f"boundaries[{i}] ({bd.id!r} at node {bd.node!r})"))
    ob_type, ob_i1, ob_i2, ob_w, observables = _observables(network, grid)
    fr_type = channels.slot_type
    friction_values = channels.slot_value
    lk_ftype = fr_type[channels.link_slot]
    level_points = forcing["b_hp"][forcing["b_type"] == BOUNDARY_LEVEL]
    plan = solver_plan(n_hp, lk_type, lk_k1, lk_k2, lk_nb, lk_ns, lk_ftype, level_points, forcing["lat_hp"])
    columns = {key: i for i, key in enumerate(forcing_keys)}
    structure_arrays = _structure_arrays(network, weirs, culverts, bridges, pumps, orifices, uweirs,
                                         channels.profile_table, columns)
    extra = StructureArrays(*(structure_arrays[name] for name in ("c_extra", "o_par", "u_par", "u_strip",
                                                                 "set_col")),
                            links=_extended_links(lk_type, lk_sidx, structure_arrays, n_culverts=len(culverts)),
                            ogate=np.zeros(len(orifices)), pnom=structure_arrays["p_cap"].copy())
    for name in ("c_extra", "o_par", "u_par", "u_strip", "set_col"):
        del structure_arrays[name]
    storage = dict(channels.storage)
    dikes = DikeArrays(sc=storage.pop("sd_sc"), hp=storage.pop("sd_hp"), rise=np.zeros(0, dtype=np.int64),
                       alt=storage.pop("sd_alt"), full=storage.pop("sd_full"), base=storage.pop("sd_base"))
    dikes = dikes._replace(rise=storage["sc_prof"][dikes.sc].astype(np.int64))
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
        lk_p1=channels.link_p1,
        lk_b1=channels.link_b1,
        lk_p2=channels.link_p2,
        lk_b2=channels.link_b2,
        lk_fric=channels.link_slot,
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
        dl_link=drop_links(lk_type, lk_k1, lk_k2, channels.link_b1, channels.link_b2, channels.storage["hp_bed"]),
        of_link=np.flatnonzero((lk_nb == NB_OUTFALL).any(axis=0)).astype(np.int64),
        fr_type=fr_type,
        **structure_arrays,
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
        arrays=_narrow(arrays),
        structures=extra,
        dikes=dikes,
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
        friction_slots=channels.slot_key,
        friction_mixed=channels.mixed_groups,
    )


def _structure_arrays(network: Network, weirs: list[Weir], culverts: list[Culvert], bridges: list[Bridge],
                      pumps: list[Pump], orifices: list[Orifice], uweirs: list[UniversalWeir],
                      profile_table: dict[str, int], columns: dict[str, int]) -> dict[str, np.ndarray]:
    """The ``w_*``, ``c_*``, ``p_*``, ``o_*`` and ``u_*`` arrays (one entry per structure; bridges after culverts)."""
    profiles = {p.id: p for p in network.profiles}

    def barrel(c: Culvert | Bridge) -> tuple[int, float, float, int]:
        """Shape code, width (m), crown height (m) and table of a culvert or bridge barrel."""
        if isinstance(c, Culvert) and c.shape != "profile":
            shape = CULVERT_RECTANGULAR if c.shape == "rectangular" else CULVERT_CIRCULAR
            return shape, float(c.width if c.shape == "rectangular" else c.diameter), c.opening_height, -1
        p = profiles[c.profile]
        crown = 1.0e10
        if isinstance(p, CircularProfile):
            crown = p.diameter
        elif getattr(p, "closed", False):
            crown = p.height if p.type == "rectangular" else p.heights[-1]
        return CULVERT_PROFILE, 0.0, float(crown), profile_table[p.id]

    barrels = [barrel(c) for c in [*culverts, *bridges]]
    inverts = [c.inverts for c in culverts] + [(b.bed_level, b.bed_level) for b in bridges]
    strips_w, strips_z, u_ptr = [], [], [0]
    for u in uweirs:
        for k in range(len(u.y) - 1):
            (ya, za), (yb, zb) = (u.y[k], u.z[k]), (u.y[k + 1], u.z[k + 1])
            if yb <= ya:
                continue
            n = 1 if za == zb else 8  # a sloping piece of the crest in strips
            for k in range(n):
                strips_w.append((yb - ya) / n)
                strips_z.append(u.crest_level + za + (zb - za) * (k + 0.5) / n)
        u_ptr.append(len(strips_w))
    as_float = lambda v: np.asarray(v, dtype=float)  # noqa: E731
    as_int = lambda v: np.asarray(v, dtype=np.int64)  # noqa: E731
    o_par = np.zeros((len(orifices), O_WIDTH))
    for k, o in enumerate(orifices):
        o_par[k] = (o.crest_level, o.crest_width, o.gate_lower_edge_level, o.discharge_coefficient,
                    DIRECTION_CODES[o.allowed_flow], np.inf if o.max_flow_positive is None else o.max_flow_positive,
                    np.inf if o.max_flow_negative is None else o.max_flow_negative)
    u_par = np.zeros((len(uweirs), U_WIDTH))
    for k, u in enumerate(uweirs):
        u_par[k] = (u.discharge_coefficient, DIRECTION_CODES[u.allowed_flow], u_ptr[k], u_ptr[k + 1])
    c_extra = np.zeros((len(barrels), C_WIDTH))
    for k, (inv, b) in enumerate(zip(inverts, barrels, strict=True)):
        c_extra[k] = (inv[1], float(culverts[k].outlet_expansion) if k < len(culverts) else 1.0, b[3])
    set_col = ([columns.get(f"crest:{w.id}", -1) for w in weirs] + [columns.get(f"gate:{o.id}", -1) for o in orifices]
               + [columns.get(f"capacity:{p.id}", -1) for p in pumps])
    return dict(
        w_width=as_float([w.crest_width for w in weirs]),
        w_cmu=as_float([w.discharge_coefficient * w.lateral_contraction for w in weirs]),
        w_dir=as_int([DIRECTION_CODES[w.allowed_flow] for w in weirs]),
        c_shape=as_int([b[0] for b in barrels]),
        c_width=as_float([b[1] for b in barrels]),
        c_height=as_float([b[2] for b in barrels]),
        c_invert=as_float([i[0] for i in inverts]),
        c_length=as_float([c.length for c in [*culverts, *bridges]]),
        c_xin=as_float([c.inlet_loss + c.bend_loss for c in culverts] + [b.inlet_loss for b in bridges]),
        c_xout=as_float([c.outlet_loss for c in [*culverts, *bridges]]),
        c_ftype=as_int([FRICTION_CODES[c.friction.type] for c in [*culverts, *bridges]]),
        c_fval=as_float([c.friction.value for c in [*culverts, *bridges]]),
        c_dir=as_int([DIRECTION_CODES[c.allowed_flow] for c in [*culverts, *bridges]]),
        c_extra=c_extra,
        p_cap=as_float([p.capacity for p in pumps]),
        p_on=as_float([p.start_level for p in pumps]),
        p_off=as_float([p.stop_level for p in pumps]),
        p_sign=as_float([1.0 if p.direction == "positive" else -1.0 for p in pumps]),
        o_par=o_par,
        u_par=u_par,
        u_strip=np.column_stack([as_float(strips_w), as_float(strips_z)]).reshape(-1, 2),
        set_col=as_int(set_col),
    )


def _forcing(network: Network, grid: Grid, critical) -> tuple[dict[str, np.ndarray], list[str], list[bool]]:
    """The ``b_*`` and ``lat_*`` arrays, and the forcing columns: boundaries, laterals, then structure settings.

    Returns the arrays, the key of each forcing column (``boundary:<id>``, ``lateral:<id>``, ``crest:<weir>``,
    ``gate:<orifice>``, ``capacity:<pump>``) and whether it holds a level (m AD; the value at the end of a
    step) rather than a discharge (m³/s; the step mean). A rating boundary has no column (-1); a critical
    boundary is a rating boundary whose table ``critical(index, boundary)`` gives (levels, discharges).
    """
    keys: list[str] = []
    is_level: list[bool] = []
    b_hp, b_type, b_col, b_rptr, b_rlev, b_rq = [], [], [], [0], [], []
    for i, bd in enumerate(network.boundaries):
        b_hp.append(grid.node_index[bd.node])
        b_type.append(_BOUNDARY_CODES[bd.type])
        if bd.type == "rating":
            b_col.append(-1)
            b_rlev.extend(bd.rating.levels)
            b_rq.extend(bd.rating.discharges)
        elif bd.type == "critical":
            b_col.append(-1)
            levels, discharges = critical(i, bd)
            b_rlev.extend(levels)
            b_rq.extend(discharges)
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
    for table, prefix, name, level in (("weirs", "crest", "crest_series", True),
                                       ("orifices", "gate", "gate_series", True),
                                       ("pumps", "capacity", "capacity_series", False)):
        for item in getattr(network, table):
            if getattr(item, name) is not None:
                keys.append(f"{prefix}:{item.id}")
                is_level.append(level)
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


def critical_rating(point: int, lk_k1: np.ndarray, lk_k2: np.ndarray, lk_type: np.ndarray, link_p1: np.ndarray,
                    link_b1: np.ndarray, link_p2: np.ndarray, link_b2: np.ndarray, tables: dict,
                    what: str = "a critical boundary") -> tuple[list, list]:
    """The Q(h) table of a free outfall at end point ``point``: levels (m AD) and critical discharges (m³/s).

    At a free overfall the depth at the brink is the critical depth (Chow 1959, *Open-channel hydraulics*,
    §3-4), where the Froude number Q² T / (g A³) is one: Q = A √(g A / T), with the flow area A (m²) and top
    width T (m) of the cross-section of the channel link that reaches the point, at that end, above the bed
    there. The table follows the profile table's depths (``CRITICAL_LEVELS`` levels from the bed to the
    table's top, where the walls turn vertical; the engine extends it linearly above).

    Raises
    ------
    CaseError
        When a structure, not a channel, reaches the point (``what`` names the boundary in the message).
    """
    at_point = np.flatnonzero(((lk_k1 == point) | (lk_k2 == point)) & (lk_type == LINK_CHANNEL))
    if at_point.size != 1:
        raise CaseError("a critical boundary (a free outfall) needs the channel itself to reach its end node, but "
                        "a structure sits at the end: move the structure away from the branch end, or use a rating "
                        "boundary", field=what)
    link = int(at_point[0])
    prof, bed = (link_p1[link], link_b1[link]) if lk_k1[link] == point else (link_p2[link], link_b2[link])
    off, n, dd = int(tables["tab_off"][prof]), int(tables["tab_n"][prof]), float(tables["tab_dd"][prof])
    area = tables["tab_af"][off:off + n]
    width = np.gradient(area, dd)
    depth = np.arange(n) * dd
    keep = np.unique(np.linspace(0, n - 1, min(n, CRITICAL_LEVELS)).round().astype(int))
    q = np.zeros(keep.size)
    wet = (area[keep] > 0.0) & (width[keep] > 0.0)
    q[wet] = area[keep][wet] * np.sqrt(G * area[keep][wet] / width[keep][wet])
    return (bed + depth[keep]).tolist(), np.maximum.accumulate(q).tolist()


def _extended_links(lk_type: np.ndarray, lk_sidx: np.ndarray, arrays: dict, n_culverts: int) -> np.ndarray:
    """The links whose structure has a D-HYDRO extension (done by :func:`.structures.extended_coefficients`).

    Orifices, universal weirs, culverts with two inverts, a profile barrel or the expansion loss, and bridges
    (the culverts after the first ``n_culverts``).
    """
    extra = arrays["c_extra"]
    out = []
    for link in np.flatnonzero(lk_type != LINK_CHANNEL):
        s = lk_sidx[link]
        if lk_type[link] in (LINK_ORIFICE, LINK_UNIVERSAL_WEIR):
            out.append(link)
        elif lk_type[link] == LINK_CULVERT and (s >= n_culverts or extra[s, C_EXPAND] > 0 or extra[s, C_PROF] >= 0
                                                 or extra[s, C_INVERT2] != arrays["c_invert"][s]):
            out.append(link)
    return np.asarray(out, dtype=np.int64)


def _structure_links(grid: Grid, weirs: list, culverts: list, pumps: list, orifices: list,
                     uweirs: list) -> tuple[np.ndarray, np.ndarray]:
    """Per link: its type code and its index in the arrays of its kind (-1 for a channel)."""
    kinds = ((weirs, LINK_WEIR), (culverts, LINK_CULVERT), (pumps, LINK_PUMP), (orifices, LINK_ORIFICE),
             (uweirs, LINK_UNIVERSAL_WEIR))
    position = {s.id: (code, i) for group, code in kinds for i, s in enumerate(group)}
    lk_type = np.full(grid.n_links, LINK_CHANNEL, dtype=np.int64)
    lk_sidx = np.full(grid.n_links, -1, dtype=np.int64)
    for li, s in enumerate(grid.link_structure):
        if s is not None:
            lk_type[li], lk_sidx[li] = position[s.id]
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


def own_friction_slots(compiled: CompiledNetwork, branches: Iterable[str]) -> CompiledNetwork:
    """``compiled`` with a friction slot of their own for the channel links of ``branches`` that share a group's.

    A link whose profile takes a friction group's own value (the group has no constant value for its branch)
    conveys relative to the slot ``("group", id)``, which every such branch shares. A factor that scales the
    friction of some branches only (``friction:factor:<id>``, :mod:`rivercal.engine.quantities`) needs their
    links apart: each branch's links move to a new slot ``("split", id, branch)`` with the same law and value.
    The kernels compute a link's friction from its slot's law and value alone, so a run with the same values is
    bit for bit the run without the split; ``friction:group:<id>`` sets the group's slot and its split slots
    alike (:func:`rivercal.engine.quantities.settable_table`). Returns ``compiled`` itself when nothing is split.
    """
    wanted = set(branches)
    a = compiled.arrays
    keys = list(compiled.friction_slots)
    slot_of = {key: i for i, key in enumerate(keys)}
    types, values = list(a.fr_type), list(compiled.friction_values)
    lk_fric = a.lk_fric.copy()
    for link in np.flatnonzero(a.lk_type == LINK_CHANNEL):
        branch = compiled.link_branch[link]
        key = keys[int(lk_fric[link])]
        if branch not in wanted or key[0] != "group" or len(key) != 2:
            continue
        own = ("split", key[1], branch)
        if own not in slot_of:
            slot_of[own] = len(keys)
            keys.append(own)
            types.append(types[int(lk_fric[link])])
            values.append(values[int(lk_fric[link])])
        lk_fric[link] = slot_of[own]
    if len(keys) == len(compiled.friction_slots):
        return compiled
    arrays = a._replace(lk_fric=lk_fric.astype(a.lk_fric.dtype), fr_type=np.asarray(types, dtype=a.fr_type.dtype))
    return replace(compiled, arrays=arrays, friction_values=np.asarray(values, dtype=float), friction_slots=keys)
