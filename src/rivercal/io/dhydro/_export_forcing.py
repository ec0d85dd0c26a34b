"""The structure, storage, initial-state, forcing and station files of an export.

:class:`_ForcingFiles` is the part of the export's writer (:class:`rivercal.io.dhydro._export._Writer`) that
writes ``structures.ini`` and ``structures.bc``, ``nodeFile.ini``, ``initialFields.ini`` and its 1dField files,
``boundaries.ext`` and ``boundaries.bc``, ``obs.ini`` and ``obscrs.ini``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.io.dhydro._export_models import _ext_model, _forcing_model
from rivercal.io.dhydro._export_network import _FRICTION

__all__: list[str] = []  # the writer's part here, _ForcingFiles, is private


class _ForcingFiles:
    """The structure, storage, initial, forcing and station files of :class:`rivercal.io.dhydro._export._Writer`.

    ``structures`` adds the culverts' own definitions to the cross-section definitions ``cross_sections``
    (:class:`rivercal.io.dhydro._export_network._NetworkFiles`) left, so it runs after it.
    """

    # -- structures ----------------------------------------------------------------------------------

    def _series_forcing(self, key: str, name: str, quantity: str, unit: str):
        """A .bc time-series block of a forcing key (for structure settings, boundaries, laterals)."""
        from hydrolib.core.dflowfm.bc.models import QuantityUnitPair, TimeSeries

        series = self.forcing[key]
        held = _with_spinup(series, self.start, self.case.start)
        minutes = (held.index - self.start).total_seconds().to_numpy() / 60.0
        unit_time = f"minutes since {self.start.strftime('%Y-%m-%d %H:%M:%S')}"
        return TimeSeries(name=name, function="timeseries", timeinterpolation="linear",
                          quantityunitpair=[QuantityUnitPair(quantity="time", unit=unit_time),
                                            QuantityUnitPair(quantity=quantity, unit=unit)],
                          datablock=[[float(t), float(v)] for t, v in zip(minutes, held.to_numpy(), strict=True)])

    def structures(self):
        from hydrolib.core.dflowfm.crosssection.models import CircleCrsDef, RectangleCrsDef
        from hydrolib.core.dflowfm.structure import models as sm

        items = []
        blocks = []
        bc = _forcing_model()(forcing=[])
        bc.filepath = Path("structures.bc")

        def setting(key, name, quantity, unit, constant):
            if key in self.case.forcing:
                blocks.append(self._series_forcing(key, name, quantity, unit))
                return bc
            return constant

        for w in self.net.weirs:
            crest = setting(f"crest:{w.id}", w.id, "weir_crestLevel", "m", w.crest_level)
            items.append(sm.Weir(id=w.id, name=w.id, branchid=w.branch, chainage=w.chainage,
                                 allowedflowdir=w.allowed_flow, crestlevel=crest, crestwidth=w.crest_width,
                                 corrcoeff=w.discharge_coefficient * w.lateral_contraction, usevelocityheight=False))
        for c in self.net.culverts:
            if c.shape == "profile":
                csdef = c.profile
            else:
                csdef = f"culvert_{c.id}"
                if c.shape == "circular":
                    self._defs.append(CircleCrsDef(id=csdef, diameter=c.diameter))
                else:
                    self._defs.append(RectangleCrsDef(id=csdef, width=c.width, height=c.height, closed=True))
            left, right = c.inverts
            items.append(sm.Culvert(id=c.id, name=c.id, branchid=c.branch, chainage=c.chainage,
                                    allowedflowdir=c.allowed_flow, leftlevel=left, rightlevel=right, csdefid=csdef,
                                    length=c.length, inletlosscoeff=c.inlet_loss, outletlosscoeff=c.outlet_loss,
                                    valveonoff=False, bedfrictiontype=_FRICTION[c.friction.type],
                                    bedfriction=c.friction.value, bendlosscoeff=c.bend_loss or None))
        for p in self.net.pumps:
            cap = setting(f"capacity:{p.id}", p.id, "pump_capacity", "m3/s", p.capacity)
            items.append(sm.Pump(id=p.id, name=p.id, branchid=p.branch, chainage=p.chainage, orientation=p.direction,
                                 controlside="suctionSide", numstages=1, capacity=cap,
                                 startlevelsuctionside=[p.start_level], stoplevelsuctionside=[p.stop_level]))
        for o in self.net.orifices:
            gate = setting(f"gate:{o.id}", o.id, "orifice_gateLowerEdgeLevel", "m", o.gate_lower_edge_level)
            items.append(sm.Orifice(id=o.id, name=o.id, branchid=o.branch, chainage=o.chainage,
                                    allowedflowdir=o.allowed_flow, crestlevel=o.crest_level, crestwidth=o.crest_width,
                                    gateloweredgelevel=gate, corrcoeff=o.discharge_coefficient, usevelocityheight=False,
                                    uselimitflowpos=o.max_flow_positive is not None, limitflowpos=o.max_flow_positive,
                                    uselimitflowneg=o.max_flow_negative is not None, limitflowneg=o.max_flow_negative))
        for u in self.net.universal_weirs:
            items.append(sm.UniversalWeir(id=u.id, name=u.id, branchid=u.branch, chainage=u.chainage,
                                          allowedflowdir=u.allowed_flow, numlevels=len(u.y), yvalues=list(u.y),
                                          zvalues=[u.crest_level + z for z in u.z], crestlevel=u.crest_level,
                                          dischargecoeff=u.discharge_coefficient))
        for b in self.net.bridges:
            items.append(sm.Bridge(id=b.id, name=b.id, branchid=b.branch, chainage=b.chainage,
                                   allowedflowdir=b.allowed_flow, csdefid=b.profile, shift=b.bed_level,
                                   inletlosscoeff=b.inlet_loss, outletlosscoeff=b.outlet_loss,
                                   frictiontype=_FRICTION[b.friction.type], friction=b.friction.value,
                                   length=b.length))
        self._crossdef_model.definition = self._defs
        if not items:
            return None
        bc.forcing = blocks
        model = sm.StructureModel(structure=items)
        model.filepath = Path("structures.ini")
        return model

    # -- storage, initial state --------------------------------------------------------------------------

    def storage_nodes(self):
        from hydrolib.core.dflowfm.storagenode.models import StorageNode, StorageNodeModel

        items = []
        beds = {}
        for b in self.net.branches:
            for node, cs in ((b.from_node, b.cross_sections[0]), (b.to_node, b.cross_sections[-1])):
                bed = b.bed_level_at(0.0 if node == b.from_node else b.length)
                beds[node] = min(beds.get(node, math.inf), bed)
                del cs
        for n in self.net.nodes:
            if n.storage_table is not None:
                t = n.storage_table
                items.append(StorageNode(id=n.id, name=n.id, nodeid=n.id, usetable=True, numlevels=len(t.levels),
                                         levels=list(t.levels), storagearea=list(t.areas), interpolate="linear"))
            elif n.storage_area > 0:
                items.append(StorageNode(id=n.id, name=n.id, nodeid=n.id, usetable=False, bedlevel=beds[n.id],
                                         area=n.storage_area, streetlevel=beds[n.id] + 1.0e4,
                                         streetstoragearea=n.storage_area, storagetype="reservoir"))
        if not items:
            return None
        model = StorageNodeModel(storagenode=items)
        model.filepath = Path("nodeFile.ini")
        return model

    def initial(self):
        """The initial field: ``[initial]`` as a global depth or level; branches' ``initial_levels`` as levels.

        Branches with initial levels get ``[Branch]`` blocks of a water-level 1dField file (chainages and levels),
        after the global field, so that D-Flow FM applies them there instead.
        """
        from hydrolib.core.base.models import DiskOnlyFileModel
        from hydrolib.core.dflowfm.inifield.models import IniFieldModel, InitialField
        from hydrolib.core.dflowfm.onedfield.models import OneDFieldBranch, OneDFieldGlobal, OneDFieldModel

        ini = self.spec.initial
        if ini.level is not None and ini.depth > 0:
            self.result.notes.append("the initial state max(bed + depth, level) has no D-Flow FM counterpart: the "
                                     "initial depth is written, the minimum level is not")
        quantity, value = ("waterdepth", ini.depth) if ini.level is None or ini.depth > 0 else ("waterlevel",
                                                                                                ini.level)
        blocks = []
        for b in self.net.branches:
            if b.initial_levels is None:
                continue
            ch, lv = [float(c) for c in b.initial_levels.chainages], [float(v) for v in b.initial_levels.levels]
            where = {"numlocations": len(ch), "chainage": ch} if len(ch) > 1 else {"numlocations": 0}
            blocks.append(OneDFieldBranch(branchid=b.id, values=lv if len(ch) > 1 else lv[:1], **where))
        files = [(quantity, f"initial_{quantity}.ini",
                  OneDFieldModel(global_=OneDFieldGlobal(quantity=quantity, unit="m", value=value),
                                 branch=blocks if quantity == "waterlevel" else []))]
        if blocks and quantity != "waterlevel":
            files.append(("waterlevel", "initial_waterlevel_branches.ini", OneDFieldModel(branch=blocks)))
        fields = []
        for q, name, model in files:
            model.save(self.out / name)
            fields.append(InitialField(quantity=q, datafile=DiskOnlyFileModel(filepath=Path(name)),
                                       datafiletype="1dField"))
        model = IniFieldModel(initial=fields)
        model.filepath = Path("initialFields.ini")
        return model

    # -- boundaries and laterals ------------------------------------------------------------------------

    def _critical_table(self, index: int) -> tuple[list[float], list[float]]:
        """Levels (m AD) and discharges (m³/s) of the engine's critical-flow table of boundary ``index``."""
        from rivercal.engine.compile import compile_network

        arrays = compile_network(self.net, self.case.spec.engine).arrays
        lo, hi = int(arrays.b_rptr[index]), int(arrays.b_rptr[index + 1])
        return arrays.b_rlev[lo:hi].tolist(), arrays.b_rq[lo:hi].tolist()

    def external_forcing(self):
        from hydrolib.core.dflowfm.bc.models import Constant, QHTable, QuantityUnitPair
        from hydrolib.core.dflowfm.ext.models import Boundary, Lateral

        bc = _forcing_model()(forcing=[])
        bc.filepath = Path("boundaries.bc")
        boundaries, laterals = [], []
        for i, b in enumerate(self.net.boundaries):
            if b.type in ("rating", "critical"):
                levels, discharges = (b.rating.levels, b.rating.discharges) if b.type == "rating" \
                    else self._critical_table(i)
                bc.forcing.append(QHTable(
                    name=b.node, function="qhtable",
                    quantityunitpair=[QuantityUnitPair(quantity="qhbnd discharge", unit="m3/s"),
                                      QuantityUnitPair(quantity="qhbnd waterlevel", unit="m")],
                    datablock=[[q, h] for q, h in zip(discharges, levels, strict=True)]))
                quantity = "qhbnd"
                if b.type == "critical":
                    self.result.notes.append(
                        f"boundary {b.id!r} is a free outfall; D-Flow FM has no such boundary: it is written as the "
                        "QH table of the critical flow at its end (the reach above it is not integrated as rivercal "
                        "does, so D-Flow FM's levels there differ)")
            else:
                quantity = "waterlevelbnd" if b.type == "level" else "dischargebnd"
                unit = "m" if b.type == "level" else "m3/s"
                if b.value is not None:
                    bc.forcing.append(Constant(name=b.node, function="constant",
                                               quantityunitpair=[QuantityUnitPair(quantity=quantity, unit=unit)],
                                               datablock=[[b.value]]))
                else:
                    bc.forcing.append(self._series_forcing(f"boundary:{b.id}", b.node, quantity, unit))
            boundaries.append(Boundary(quantity=quantity, nodeid=b.node, forcingfile=bc))
            if b.id != b.node:
                self.result.notes.append(f"boundary {b.id!r} is named after its node {b.node!r} (D-Flow FM names "
                                         "boundaries by node)")
        for lat in self.net.laterals:
            where = {"nodeid": lat.node} if lat.node is not None else {"branchid": lat.branch,
                                                                      "chainage": lat.chainage}
            if lat.value is not None:
                discharge = lat.value
            else:
                bc.forcing.append(self._series_forcing(f"lateral:{lat.id}", lat.id, "lateral_discharge", "m3/s"))
                discharge = bc
            laterals.append(Lateral(id=lat.id, name=lat.id, **where, discharge=discharge))
        model = _ext_model()(boundary=boundaries, lateral=laterals)
        model.filepath = Path("boundaries.ext")
        return model

    # -- stations --------------------------------------------------------------------------------------

    def stations(self):
        from hydrolib.core.dflowfm.obs.models import ObservationPoint, ObservationPointModel
        from hydrolib.core.dflowfm.obscrosssection.models import ObservationCrossSection, ObservationCrossSectionModel

        points, sections, skipped = [], [], []
        for st in self.net.stations:
            if st.structure is not None:
                skipped.append(st.id)
                continue
            quantities = st.quantities or ["h"]
            if "h" in quantities:
                points.append(ObservationPoint(name=st.id, branchid=st.branch, chainage=st.chainage))
            if "Q" in quantities:
                sections.append(ObservationCrossSection(name=st.id, branchid=st.branch, chainage=st.chainage))
        if skipped:
            self.result.notes.append(f"stations at a structure ({', '.join(skipped)}) are not written: D-Flow FM "
                                     "reports every structure's levels and discharge in its history file")
        obs = crs = None
        if points:
            obs = ObservationPointModel(observationpoint=points)
            obs.filepath = Path("obs.ini")
        if sections:
            crs = ObservationCrossSectionModel(observationcrosssection=sections)
            crs.filepath = Path("obscrs.ini")
        return obs, crs


def _with_spinup(series: pd.Series, start: pd.Timestamp, case_start: pd.Timestamp) -> pd.Series:
    """The series from ``start``: held at its value at ``case_start`` before it (a spin-up)."""
    if start >= case_start:
        return series
    t = (series.index - case_start).total_seconds().to_numpy()
    first = float(np.interp(0.0, t, series.to_numpy(dtype=float)))
    after = series[series.index >= case_start]
    head = pd.Series([first, first], index=pd.DatetimeIndex([start, case_start]))
    return pd.concat([head.iloc[:1], head.iloc[1:] if after.index[0] > case_start else head.iloc[:0], after])
