"""The network files of an export: the UGRID 1D network, the cross-sections and the roughness files.

:class:`_NetworkFiles` is the part of the export's writer (:class:`rivercal.io.dhydro._export._Writer`) that
writes ``network_net.nc``, ``crsdef.ini`` and ``crsloc.ini``, and the ``roughness-*.ini`` files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rivercal.engine.geometry import MIN_TOP
from rivercal.network.grid import branch_layout, chainages

__all__ = ["CLOSING_STEP", "DFLOW_SUMMER_DIKE_TRANSITION"]

_FRICTION = {"strickler": "Strickler", "manning": "Manning", "chezy": "Chezy", "white-colebrook": "WhiteColebrook"}
#: Height of the level without width that closes a closed zw profile in D-Flow FM's eyes, m.
CLOSING_STEP = 0.001
#: D-Flow FM's transition height of every summer dike (``summerDikeTransitionHeight``), m.
DFLOW_SUMMER_DIKE_TRANSITION = 0.5


class _NetworkFiles:
    """The network, cross-section and roughness files of :class:`rivercal.io.dhydro._export._Writer`.

    ``cross_sections`` leaves the definitions (``_defs``) and their file model (``_crossdef_model``) for the
    culverts' own definitions the structures add.
    """

    # -- network -------------------------------------------------------------------------------------

    def network(self):
        from hydrolib.core.dflowfm.net.models import Branch, NetworkModel

        net = self.net
        model = NetworkModel()
        model.filepath = Path("network_net.nc")
        nodes = {n.id: n for n in net.nodes}
        xy = {}
        missing = [n for n in net.nodes if n.x is None]
        for k, n in enumerate(net.nodes):
            xy[n.id] = (float(n.x), float(n.y)) if n.x is not None else (1000.0 * k, -1.0e5)
        if missing:
            self.result.notes.append(f"{len(missing)} node(s) without map coordinates were placed on a line")
        structures = {b.id: [s for s in net.structures if s.branch == b.id] for b in net.branches}
        self.points: dict[str, np.ndarray] = {}
        geo_lengths = {}
        for b in net.branches:
            chain = chainages(branch_layout(b, structures[b.id], self.spec.engine.structure_length))
            self.points[b.id] = chain
            a, c = xy[b.from_node], xy[b.to_node]
            if b.geometry:
                geometry = np.asarray(b.geometry, dtype=float)
                geometry[0], geometry[-1] = a, c
            else:
                geometry = np.array([a, c], dtype=float)
            length = float(np.hypot(*np.diff(geometry, axis=0).T).sum())
            if length <= 0:
                geometry = np.array([a, (a[0] + b.length, a[1])], dtype=float)
                length = b.length
            geo_lengths[b.id] = length
            branch = Branch(geometry=geometry, branch_offsets=chain * (length / b.length))
            model.network.mesh1d_add_branch(branch, name=b.id, force_midpoint=False, branch_order=self._order(b))
        m1 = model.network._mesh1d
        by_xy = {(round(x, 6), round(y, 6)): nid for nid, (x, y) in xy.items()}
        m1.network1d_node_id = np.array([by_xy[(round(float(x), 6), round(float(y), 6))]
                                         for x, y in zip(m1.network1d_node_x, m1.network1d_node_y, strict=True)],
                                        dtype=object)
        m1.network1d_node_long_name = m1.network1d_node_id.copy()
        ids = [str(v) for v in m1.network1d_branch_id]
        m1.network1d_branch_length = np.array([self.net.branch(i).length for i in ids], dtype=float)
        offsets = np.asarray(m1.mesh1d_node_branch_offset, dtype=float).copy()
        for k, bi in enumerate(np.asarray(m1.mesh1d_node_branch_id, dtype=int)):
            bid = ids[bi]
            chain = self.points[bid]
            offsets[k] = chain[int(np.argmin(np.abs(chain - offsets[k] * self.net.branch(bid).length
                                                    / geo_lengths[bid])))]
        m1.mesh1d_node_branch_offset = offsets
        del nodes
        return model

    def _order(self, b) -> int:
        """D-Flow FM's ``branchOrder`` of a branch: its order when positive, else -1 (none).

        D-Flow FM interpolates cross-sections across nodes between branches of every order but -1 (flow1d
        ``useBranchOrdersCrs``); the case between branches of a positive order only.
        """
        if b.order is not None and b.order > 0:
            return int(b.order)
        if b.order is not None and b.order != -1:
            self.result.notes.append(f"branch {b.id!r} has order {b.order}, which interpolates no cross-section in a "
                                     "case: written as branchOrder -1 (D-Flow FM would interpolate across nodes "
                                     "between branches of any order but -1)")
        return -1

    # -- cross-sections ----------------------------------------------------------------------------

    def cross_sections(self):
        from hydrolib.core.dflowfm.crosssection.models import CrossDefModel, CrossLocModel, CrossSection

        defs = []
        self.def_ids: dict[tuple[str, str | None], str] = {}
        for p in self.net.profiles:
            defs.append(self._definition(p, p.id, p.friction))
        locs = []
        for b in self.net.branches:
            for k, cs in enumerate(b.cross_sections):
                locs.append(CrossSection(id=f"{b.id}_{k + 1}", branchid=b.id, chainage=cs.chainage, shift=cs.bed_level,
                                         definitionid=cs.profile))
        defs += self.extra_defs
        self._defs = defs
        model_defs = CrossDefModel(definition=defs)
        model_defs.filepath = Path("crsdef.ini")
        model_locs = CrossLocModel(crosssection=locs)
        model_locs.filepath = Path("crsloc.ini")
        self._crossdef_model = model_defs
        return model_defs, model_locs

    def _definition(self, p, did: str, friction: list[str] | None):
        from hydrolib.core.dflowfm.crosssection import models as m

        ids = list(friction) if friction else [self.global_id]
        kind = p.type
        if kind == "rectangular":
            height = p.height if p.height is not None else MIN_TOP
            if not p.closed and (p.height or 0) < MIN_TOP:
                height = MIN_TOP
            return m.RectangleCrsDef(id=did, width=p.width, height=height, closed=bool(p.closed), frictionid=ids[0])
        if kind == "trapezoidal":
            top = max(p.height or 0.0, MIN_TOP)
            widths = [p.bottom_width, p.bottom_width + 2.0 * p.side_slope * top]
            return m.ZWCrsDef(id=did, numlevels=2, levels=[0.0, top], flowwidths=widths, totalwidths=widths,
                              frictionid=ids[0])
        if kind == "circular":
            return m.CircleCrsDef(id=did, diameter=p.diameter, frictionid=ids[0])
        if kind == "zw":
            return self._zw_definition(p, did, ids)
        positions = list(p.friction_positions) if p.friction_positions else [p.y[0], p.y[-1]]
        return m.YZCrsDef(id=did, yzcount=len(p.y), ycoordinates=list(p.y), zcoordinates=list(p.z),
                          conveyance=p.conveyance, sectioncount=len(positions) - 1, frictionpositions=positions,
                          frictionids=ids, singlevaluedz=True)

    def _zw_definition(self, p, did: str, ids: list[str]):
        """A zw profile as a ``zw`` definition, or ``zwRiver`` with its sections and summer dike (``levee*``).

        The levels are the heights above the profile's lowest point (the location's shift is its bed level). A
        closed profile with width left at its top gets a level 1 mm higher without width: D-Flow FM takes a table
        as closed only when no width is left at its top (flow1d ``readTabulatedCS``). A summer dike becomes
        D-Flow FM's levee with its base level at the crest, so that D-Flow FM fills and empties the storage behind
        it along the same curve as the case.
        """
        from hydrolib.core.dflowfm.crosssection import models as m

        total = list(p.storage_widths)
        heights = list(p.heights)
        flow = list(p.flow_widths)
        if p.closed and max(total[-1], flow[-1]) > 0:
            heights.append(heights[-1] + CLOSING_STEP)
            flow.append(0.0)
            total.append(0.0)
            self.result.notes.append(f"profile {p.id!r} is closed with {total[-2]:g} m of width at its top: written "
                                     f"with a level {CLOSING_STEP * 1000:g} mm higher without width, where D-Flow FM "
                                     "closes a table")
        dike = p.summer_dike
        if p.section_widths is None and dike is None:
            return m.ZWCrsDef(id=did, numlevels=len(heights), levels=heights, flowwidths=flow, totalwidths=total,
                              frictionid=ids[0])
        sections = list(p.section_widths) if p.section_widths is not None else [max(flow)]
        sw = sections + [0.0] * (3 - len(sections))
        levee = {}
        if dike is not None:
            base = dike.crest if dike.base is None else dike.base  # flow1d's falling curve ends at it
            levee = {"leveecrestLevel": dike.crest, "leveebaselevel": base, "leveeflowarea": dike.flow_area,
                     "leveetotalrea": dike.total_area}
            if abs(dike.transition - DFLOW_SUMMER_DIKE_TRANSITION) > 1e-12:
                self.result.notes.append(
                    f"the summer dike of profile {p.id!r} fills over {dike.transition:g} m above its crest; D-Flow FM "
                    f"fills every summer dike over {DFLOW_SUMMER_DIKE_TRANSITION:g} m (summerDikeTransitionHeight)")
        return m.ZWRiverCrsDef(id=did, numlevels=len(heights), levels=heights, flowwidths=flow, totalwidths=total,
                               mainwidth=sw[0], fp1width=sw[1], fp2width=sw[2],
                               frictionids=(ids + [ids[-1]] * 3)[:len(sections)], **levee)

    # -- friction ------------------------------------------------------------------------------------

    def frictions(self):
        """Roughness files: the global and the branches' own friction, then one file per friction group.

        Each value a group takes on a branch is a ``[Branch]`` block in its own law: one value, values at
        ``numLocations`` chainages, or (``functionType = waterLevel``) a table of ``numLevels`` levels by
        ``numLocations`` chainages, written level by level as D-Flow FM reads it (flow1d ``scan_roughness_input``).
        """
        from hydrolib.core.dflowfm.friction.models import FrictBranch, FrictGlobal, FrictionModel

        g = self.spec.friction
        branches = [FrictBranch(branchid=b.id, frictiontype=_FRICTION[b.friction.type], functiontype="constant",
                                numlocations=0, frictionvalues=[b.friction.value])
                    for b in self.net.branches if b.friction is not None]
        main = FrictionModel(global_=[FrictGlobal(frictionid=self.global_id, frictiontype=_FRICTION[g.type],
                                                  frictionvalue=g.value)], branch=branches)
        main.filepath = Path(f"roughness-{self.global_id}.ini")
        used = bool(branches) or any(not p.friction for p in self.net.profiles)
        models = [main] if used or self.global_id == "Main" else []  # under another name only when used
        if used and self.global_id != "Main":
            self.result.notes.append(f"the case has a friction group named Main: its global friction and the "
                                     f"branches' own are written as roughness group {self.global_id!r}, which the "
                                     "profiles without friction groups name (D-Flow FM's default group is Main)")
        for group in self.net.friction_groups:
            fm = FrictionModel(
                global_=[FrictGlobal(frictionid=group.id, frictiontype=_FRICTION[group.type],
                                     frictionvalue=group.value)],
                branch=[_branch_block(FrictBranch, bf, group.type) for bf in group.branches])
            fm.filepath = Path(f"roughness-{group.id}.ini")
            models.append(fm)
        return models


def _branch_block(cls, bf, group_law: str):
    """A ``[Branch]`` block of a roughness file for a group's entry on a branch (:class:`BranchFriction`)."""
    law = _FRICTION[bf.type or group_law]
    chainages = [float(c) for c in bf.chainages] if bf.chainages is not None else None
    where = {"numlocations": len(chainages), "chainage": chainages} if chainages is not None else {"numlocations": 0}
    if bf.function == "waterlevel":
        rows = [[float(v) for v in row] for row in bf.table]
        values = [row[j] for j in range(len(bf.levels)) for row in rows]  # numLocations values per level, in turn
        return cls(branchid=bf.branch, frictiontype=law, functiontype="waterLevel", numlevels=len(bf.levels),
                   levels=[float(v) for v in bf.levels], frictionvalues=values, **where)
    if bf.values is not None:
        return cls(branchid=bf.branch, frictiontype=law, functiontype="constant",
                   frictionvalues=[float(v) for v in bf.values], **where)
    return cls(branchid=bf.branch, frictiontype=law, functiontype="constant", numlocations=0,
               frictionvalues=[float(bf.value)])
