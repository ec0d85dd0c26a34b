"""Small D-Flow FM 1D models built with hydrolib-core, for the tests of the D-HYDRO import and export.

Every profile type (yz, zw, zwRiver, circle, open and closed rectangle, xyz) and every structure type
(weir, universal weir, orifice, culvert of each shape, siphon, bridge, pump, compound, general structure,
gate, dambreak) appears, with boundaries (constant level, discharge series, Q(h), free outfall),
laterals (constant, series, realtime), observation points, storage nodes and an initial field, so that
each conversion is tested and not only those in the shared models. The numbers put in here are the
reference the tests compare the case with.

The network is a line ``A -(b1)- B -(b2)- C -(b3)- D`` with a side branch ``B -(b4)- E``: four branches
of 1 km on a straight line (b4 goes north), calculation points every 100 m.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

REFDATE = 20200101
NODES = {"A": (0.0, 0.0), "B": (1000.0, 0.0), "C": (2000.0, 0.0), "D": (3000.0, 0.0), "E": (1000.0, 1000.0)}
BRANCHES = {"b1": ("A", "B"), "b2": ("B", "C"), "b3": ("C", "D"), "b4": ("B", "E")}
LENGTH = 1000.0
DX = 100.0


def write_network(folder: Path, branches: dict[str, tuple[str, str]] = BRANCHES,
                  nodes: dict[str, tuple[float, float]] = NODES, dx: float = DX):
    """The UGRID network (a NetworkModel, saved as ``net.nc``) with nodes named as in ``nodes``."""
    from hydrolib.core.dflowfm.net.models import Branch, NetworkModel

    model = NetworkModel()
    for name, (a, b) in branches.items():
        geometry = np.array([nodes[a], nodes[b]], dtype=float)
        length = float(np.hypot(*(geometry[1] - geometry[0])))
        offsets = np.linspace(0.0, length, round(length / dx) + 1)
        model.network.mesh1d_add_branch(Branch(geometry=geometry, branch_offsets=offsets), name=name,
                                        force_midpoint=False)
    m1 = model.network._mesh1d
    by_xy = {xy: n for n, xy in nodes.items()}
    m1.network1d_node_id = np.array([by_xy[(float(x), float(y))] for x, y in zip(m1.network1d_node_x,
                                                                                 m1.network1d_node_y, strict=True)],
                                    dtype=object)
    m1.network1d_node_long_name = m1.network1d_node_id.copy()
    model.filepath = Path("net.nc")
    return model


def cross_sections():
    """Definitions of every type and their locations: two per channel branch."""
    from hydrolib.core.dflowfm.crosssection import models as m

    defs = [
        m.YZCrsDef(id="yz1", yzcount=6, ycoordinates=[0.0, 2.0, 4.0, 6.0, 8.0, 10.0],
                   zcoordinates=[3.0, 1.0, 0.0, 0.0, 1.0, 3.0], conveyance="segmented", sectioncount=2,
                   frictionpositions=[0.0, 5.0, 10.0], frictionids=["Main", "Grass"]),
        m.ZWCrsDef(id="zw1", numlevels=3, levels=[-1.0, 0.0, 2.0], flowwidths=[4.0, 6.0, 10.0],
                   totalwidths=[4.0, 8.0, 20.0], frictionid="Main"),
        m.ZWRiverCrsDef(id="river1", numlevels=3, levels=[-1.0, 0.5, 2.0], flowwidths=[5.0, 10.0, 30.0],
                        totalwidths=[5.0, 12.0, 40.0], mainwidth=10.0, fp1width=20.0, fp2width=0.0,
                        frictionids=["Main", "Grass", "Grass"]),
        m.CircleCrsDef(id="pipe1", diameter=1.2, frictionid="Concrete"),
        m.RectangleCrsDef(id="box1", width=3.0, height=2.0, closed=True, frictionid="Concrete"),
        m.RectangleCrsDef(id="open1", width=5.0, height=3.0, closed=False),
        m.XYZCrsDef(id="xyz1", xyzcount=4, xcoordinates=[0.0, 3.0, 6.0, 9.0], ycoordinates=[0.0, 4.0, 8.0, 12.0],
                    zcoordinates=[2.0, 0.0, 0.0, 2.0], conveyance="lumped", frictionids=["Main"],
                    frictionpositions=[0.0, 15.0]),
        m.CircleCrsDef(id="culvert_round", diameter=0.8),
        m.RectangleCrsDef(id="culvert_box", width=1.5, height=1.0, closed=True),
        m.ZWCrsDef(id="egg", numlevels=4, levels=[0.0, 0.3, 0.9, 1.2], flowwidths=[0.0, 0.8, 0.6, 0.0],
                   totalwidths=[0.0, 0.8, 0.6, 0.0]),
        m.RectangleCrsDef(id="bridge_opening", width=6.0, height=4.0, closed=False),
        m.ZWCrsDef(id="unused", numlevels=2, levels=[0.0, 1.0], flowwidths=[1.0, 1.0]),
    ]
    locs = [
        m.CrossSection(id="b1_up", branchid="b1", chainage=0.0, shift=0.0, definitionid="yz1"),
        m.CrossSection(id="b1_down", branchid="b1", chainage=1000.0, shift=-0.5, definitionid="zw1"),
        m.CrossSection(id="b2_up", branchid="b2", chainage=50.0, shift=-0.5, definitionid="river1"),
        m.CrossSection(id="b2_down", branchid="b2", chainage=900.0, shift=-0.8, definitionid="xyz1"),
        m.CrossSection(id="b3_up", branchid="b3", chainage=0.0, shift=-1.0, definitionid="open1"),
        m.CrossSection(id="b3_mid", branchid="b3", chainage=500.0, shift=-1.1, definitionid="box1"),
        m.CrossSection(id="b3_down", branchid="b3", chainage=1000.0, shift=-1.2, definitionid="pipe1"),
        m.CrossSection(id="b4_up", branchid="b4", chainage=500.0, shift=0.2, definitionid="zw1"),
    ]
    model_defs = m.CrossDefModel(definition=defs)
    model_defs.filepath = Path("crsdef.ini")
    model_locs = m.CrossLocModel(crosssection=locs)
    model_locs.filepath = Path("crsloc.ini")
    return model_defs, model_locs


def frictions():
    """Roughness: Main (Chézy 45, Manning 0.03 on b4), Grass (Strickler 20), Concrete (White-Colebrook)."""
    from hydrolib.core.dflowfm.friction.models import FrictBranch, FrictGlobal, FrictionModel

    main = FrictionModel(global_=[FrictGlobal(frictionid="Main", frictiontype="Chezy", frictionvalue=45.0)],
                         branch=[FrictBranch(branchid="b4", frictiontype="Manning", functiontype="constant",
                                             numlocations=0, frictionvalues=[0.03])])
    main.filepath = Path("roughness-Main.ini")
    grass = FrictionModel(global_=[FrictGlobal(frictionid="Grass", frictiontype="Strickler", frictionvalue=20.0)],
                          branch=[FrictBranch(branchid="b2", frictiontype="Strickler", functiontype="constant",
                                              numlocations=2, chainage=[0.0, 1000.0], frictionvalues=[22.0, 26.0])])
    grass.filepath = Path("roughness-Grass.ini")
    concrete = FrictionModel(global_=[FrictGlobal(frictionid="Concrete", frictiontype="WhiteColebrook",
                                                  frictionvalue=0.003)])
    concrete.filepath = Path("roughness-Concrete.ini")
    return [main, grass, concrete]


def structures(folder: Path):
    """One structure of each type; the weir's crest follows a .bc series."""
    from hydrolib.core.dflowfm.bc.models import ForcingModel, QuantityUnitPair, TimeSeries
    from hydrolib.core.dflowfm.structure import models as s

    crest = ForcingModel(forcing=[TimeSeries(
        name="weir1", function="timeseries", timeinterpolation="linear",
        quantityunitpair=[QuantityUnitPair(quantity="time", unit="minutes since 2020-01-01 00:00:00"),
                          QuantityUnitPair(quantity="weir_crestLevel", unit="m")],
        datablock=[[0.0, 0.5], [120.0, 0.5], [180.0, 0.8], [1440.0, 0.8]])])
    crest.save(folder / "crest.bc")
    crest.filepath = Path("crest.bc")
    items = [
        s.Weir(id="weir1", branchid="b1", chainage=450.0, allowedflowdir="both", crestlevel=crest, crestwidth=4.0,
               corrcoeff=0.9, usevelocityheight=True),
        s.UniversalWeir(id="uweir1", branchid="b1", chainage=850.0, allowedflowdir="positive", numlevels=4,
                        yvalues=[0.0, 1.0, 3.0, 4.0], zvalues=[1.0, 0.3, 0.3, 1.0], crestlevel=0.3,
                        dischargecoeff=0.85),
        s.Orifice(id="orifice1", branchid="b2", chainage=250.0, allowedflowdir="both", crestlevel=-0.2,
                  crestwidth=3.0, gateloweredgelevel=0.6, corrcoeff=0.63, usevelocityheight=False,
                  uselimitflowpos=True, limitflowpos=5.0),
        s.Culvert(id="culvert1", branchid="b2", chainage=550.0, allowedflowdir="both", leftlevel=-0.4,
                  rightlevel=-0.45, csdefid="culvert_round", length=12.0, inletlosscoeff=0.6, outletlosscoeff=0.9,
                  valveonoff=False, bedfrictiontype="Manning", bedfriction=0.014),
        s.Culvert(id="culvert2", branchid="b3", chainage=150.0, allowedflowdir="negative", leftlevel=-0.9,
                  rightlevel=-0.9, csdefid="culvert_box", length=8.0, inletlosscoeff=0.5, outletlosscoeff=1.0,
                  valveonoff=False, bedfrictiontype="Strickler", bedfriction=75.0),
        s.Culvert(id="siphon1", branchid="b3", chainage=350.0, allowedflowdir="both", leftlevel=-2.0,
                  rightlevel=-2.1, csdefid="egg", length=30.0, inletlosscoeff=0.5, outletlosscoeff=1.0,
                  valveonoff=False, bedfrictiontype="Strickler", bedfriction=70.0, subtype="invertedSiphon",
                  bendlosscoeff=0.4),
        s.Bridge(id="bridge1", branchid="b3", chainage=750.0, allowedflowdir="both", csdefid="bridge_opening",
                 shift=-1.15, inletlosscoeff=0.3, outletlosscoeff=0.8, frictiontype="Strickler", friction=40.0,
                 length=10.0),
        s.Pump(id="pump1", branchid="b4", chainage=650.0, orientation="positive", controlside="suctionSide",
               numstages=1, capacity=0.5, startlevelsuctionside=[1.2], stoplevelsuctionside=[0.9]),
        s.Compound(id="compound1", branchid="b4", chainage=650.0, numstructures=1, structureids=["pump1"]),
        s.GeneralStructure(id="general1", branchid="b4", chainage=250.0, allowedflowdir="both", crestlevel=0.5,
                           crestwidth=2.0, gateloweredgelevel=1.5, posfreegateflowcoeff=0.9,
                           poscontrcoeffreegate=0.7),
        s.Dambreak(id="dambreak1", startlocationx=1500.0, startlocationy=0.0, algorithm=2, crestlevelini=2.0,
                   breachwidthini=1.0, crestlevelmin=0.0, t0=0.0, timetobreachtomaximumdepth=3600.0, f1=1.0,
                   f2=1.0, ucrit=0.2, numcoordinates=2, xcoordinates=[1500.0, 1500.0],
                   ycoordinates=[-10.0, 10.0], waterlevelupstreamnodeid="B", waterleveldownstreamnodeid="C"),
    ]
    model = s.StructureModel(structure=items)
    model.filepath = Path("structures.ini")
    return model


def forcing():
    """Boundaries (A: discharge series, D: constant level, E: Q(h)) and laterals (constant, series, realtime)."""
    from hydrolib.core.dflowfm.bc.models import Constant, ForcingModel, QHTable, QuantityUnitPair, TimeSeries
    from hydrolib.core.dflowfm.ext.models import Boundary, ExtModel, Lateral

    unit = "minutes since 2020-01-01 00:00:00"
    bc = ForcingModel(forcing=[
        TimeSeries(name="A", function="timeseries", timeinterpolation="linear",
                   quantityunitpair=[QuantityUnitPair(quantity="time", unit=unit),
                                     QuantityUnitPair(quantity="dischargebnd", unit="m3/s")],
                   datablock=[[0.0, 2.0], [360.0, 6.0], [720.0, 3.0], [1440.0, 3.0]]),
        Constant(name="D", function="constant", quantityunitpair=[QuantityUnitPair(quantity="waterlevelbnd",
                                                                                   unit="m")], datablock=[[0.4]]),
        QHTable(name="E", function="qhtable",
                quantityunitpair=[QuantityUnitPair(quantity="qhbnd discharge", unit="m3/s"),
                                  QuantityUnitPair(quantity="qhbnd waterlevel", unit="m")],
                datablock=[[0.0, 0.8], [1.0, 1.1], [4.0, 1.6]]),
        TimeSeries(name="lat_series", function="timeseries", timeinterpolation="linear",
                   quantityunitpair=[QuantityUnitPair(quantity="time", unit=unit),
                                     QuantityUnitPair(quantity="lateral_discharge", unit="m3/s")],
                   datablock=[[0.0, 0.1], [720.0, 0.3], [1440.0, 0.1]]),
    ])
    bc.filepath = Path("boundaries.bc")
    ext = ExtModel(
        boundary=[Boundary(quantity="dischargebnd", nodeid="A", forcingfile=bc),
                  Boundary(quantity="waterlevelbnd", nodeid="D", forcingfile=bc),
                  Boundary(quantity="qhbnd", nodeid="E", forcingfile=bc)],
        lateral=[Lateral(id="lat_const", branchid="b1", chainage=300.0, discharge=0.2),
                 Lateral(id="lat_series", branchid="b2", chainage=700.0, discharge=bc),
                 Lateral(id="lat_node", nodeid="C", discharge="realtime")])
    ext.filepath = Path("forcing.ext")
    return ext


def write_model(folder: Path) -> Path:
    """Write the test model into ``folder``; returns the MDU path."""
    from hydrolib.core.base.models import DiskOnlyFileModel
    from hydrolib.core.dflowfm.inifield.models import IniFieldModel, InitialField
    from hydrolib.core.dflowfm.mdu.models import FMModel
    from hydrolib.core.dflowfm.obs.models import ObservationPoint, ObservationPointModel
    from hydrolib.core.dflowfm.onedfield.models import OneDFieldGlobal, OneDFieldModel
    from hydrolib.core.dflowfm.storagenode.models import StorageNode, StorageNodeModel

    folder.mkdir(parents=True, exist_ok=True)
    fm = FMModel()
    fm.filepath = folder / "test.mdu"
    fm.geometry.netfile = write_network(folder)
    fm.geometry.crossdeffile, fm.geometry.crosslocfile = cross_sections()
    fm.geometry.frictfile = frictions()
    fm.geometry.structurefile = [structures(folder)]
    storage = StorageNodeModel(storagenode=[
        StorageNode(id="sB", name="sB", nodeid="B", usetable=False, bedlevel=-1.0, area=20.0, streetlevel=2.0,
                    streetstoragearea=500.0, storagetype="reservoir"),
        StorageNode(id="sC", name="sC", nodeid="C", usetable=True, numlevels=3, levels=[-1.5, 0.0, 1.0],
                    storagearea=[5.0, 10.0, 50.0], interpolate="linear"),
    ])
    storage.filepath = Path("nodes.ini")
    fm.geometry.storagenodefile = storage
    OneDFieldModel(global_=OneDFieldGlobal(quantity="waterdepth", unit="m", value=0.7)).save(folder / "depth.ini")
    ini = IniFieldModel(initial=[InitialField(quantity="waterdepth", datafile=DiskOnlyFileModel(filepath=Path(
        "depth.ini")), datafiletype="1dField")])
    ini.filepath = Path("initialFields.ini")
    fm.geometry.inifieldfile = ini
    fm.external_forcing.extforcefilenew = forcing()
    obs = ObservationPointModel(observationpoint=[
        ObservationPoint(name="obs_b1", branchid="b1", chainage=200.0),
        ObservationPoint(name="obs.xy", x=1500.0, y=3.0, locationtype="1d"),
        ObservationPoint(name="obs_nowhere", x=1.0e6, y=1.0e6, locationtype="1d"),
    ])
    obs.filepath = Path("obs.ini")
    fm.output.obsfile = [obs]
    fm.output.hisinterval = [600.0, 0.0, 0.0]
    fm.time.refdate = REFDATE
    fm.time.tunit = "S"
    fm.time.tstart = 0.0
    fm.time.tstop = 86400.0
    fm.time.dtmax = 30.0
    fm.physics.uniffricttype = 1
    fm.physics.uniffrictcoef1d = 0.025
    fm.save(recurse=True)
    return fm.filepath


# -- a model with the friction and cross-section features of real water-board models ------------------------------

#: The feature model: ``A -(b1)- B -(bc)- C -(b2)- D`` on a line, all of branch order 1 (``bc`` a 100 m connector
#: without cross-sections), and a side branch ``C -(b3)- E`` of order 2 going north.
FEATURE_NODES = {"A": (0.0, 0.0), "B": (1000.0, 0.0), "C": (1100.0, 0.0), "D": (2100.0, 0.0), "E": (1100.0, 800.0)}
FEATURE_BRANCHES = {"b1": ("A", "B"), "bc": ("B", "C"), "b2": ("C", "D"), "b3": ("C", "E")}
FEATURE_ORDERS = {"b1": 1, "bc": 1, "b2": 1, "b3": 2}
#: Cross-sections of the feature model: branch → (chainage m, definition, shift = bed level m AD).
FEATURE_SECTIONS = {"b1": [(200.0, "river", 0.5)], "b2": [(500.0, "plain", -0.5)], "b3": [(500.0, "narrowing", 0.0)]}
#: Group Grass on b1: Manning n by chainage (rows) and water level (columns) — a law of its own in a Strickler group.
GRASS_LEVELS = [0.5, 1.5, 2.5]
GRASS_CHAINAGES = [0.0, 1000.0]
GRASS_TABLE = [[0.040, 0.035, 0.030], [0.045, 0.040, 0.032]]


def feature_frictions(*, discharge_dependent: bool = False):
    """Roughness of the feature model.

    - ``Main`` (Chézy 40): Manning 0.03 on b1 (a law of its own); Chézy 35 → 45 along b2 (so Main stays a group);
    - ``Grass`` (Strickler 25): a water-level table in Manning on b1 (:data:`GRASS_TABLE`), Strickler 30 on b3 — or,
      with ``discharge_dependent``, a table of the discharge on b3 (``functionType = absDischarge``).
    """
    from hydrolib.core.dflowfm.friction.models import FrictBranch, FrictGlobal, FrictionModel

    main = FrictionModel(global_=[FrictGlobal(frictionid="Main", frictiontype="Chezy", frictionvalue=40.0)],
                         branch=[FrictBranch(branchid="b1", frictiontype="Manning", functiontype="constant",
                                             numlocations=0, frictionvalues=[0.03]),
                                 FrictBranch(branchid="b2", frictiontype="Chezy", functiontype="constant",
                                             numlocations=2, chainage=[0.0, 1000.0], frictionvalues=[35.0, 45.0])])
    main.filepath = Path("roughness-Main.ini")
    values = [row[j] for j in range(len(GRASS_LEVELS)) for row in GRASS_TABLE]  # level by level, as D-Flow FM reads
    b3 = (FrictBranch(branchid="b3", frictiontype="Strickler", functiontype="absDischarge", numlevels=2,
                      levels=[0.0, 10.0], numlocations=0, frictionvalues=[28.0, 32.0]) if discharge_dependent
          else FrictBranch(branchid="b3", frictiontype="Strickler", functiontype="constant", numlocations=0,
                           frictionvalues=[30.0]))
    grass = FrictionModel(global_=[FrictGlobal(frictionid="Grass", frictiontype="Strickler", frictionvalue=25.0)],
                          branch=[FrictBranch(branchid="b1", frictiontype="Manning", functiontype="waterLevel",
                                              numlevels=len(GRASS_LEVELS), levels=GRASS_LEVELS,
                                              numlocations=len(GRASS_CHAINAGES), chainage=GRASS_CHAINAGES,
                                              frictionvalues=values), b3])
    grass.filepath = Path("roughness-Grass.ini")
    return [main, grass]


def write_feature_model(folder: Path, *, discharge_dependent: bool = False) -> Path:
    """A small D-Flow FM model with every friction and cross-section feature; returns the MDU path.

    Branch orders (with a connector branch without cross-sections), per-branch friction laws, friction along a
    branch and as a function of the water level, a zwRiver profile with floodplain sections and a summer dike
    (levee), an open zw profile whose flow width narrows, initial levels along a branch, a discharge into A and E
    and a level at D, and an observation point on every branch with a cross-section.
    """
    from hydrolib.core.base.models import DiskOnlyFileModel
    from hydrolib.core.dflowfm.bc.models import Constant, ForcingModel, QuantityUnitPair
    from hydrolib.core.dflowfm.crosssection import models as m
    from hydrolib.core.dflowfm.ext.models import Boundary, ExtModel
    from hydrolib.core.dflowfm.inifield.models import IniFieldModel, InitialField
    from hydrolib.core.dflowfm.mdu.models import FMModel
    from hydrolib.core.dflowfm.obs.models import ObservationPoint, ObservationPointModel
    from hydrolib.core.dflowfm.onedfield.models import OneDFieldBranch, OneDFieldGlobal, OneDFieldModel

    folder.mkdir(parents=True, exist_ok=True)
    fm = FMModel()
    fm.filepath = folder / "features.mdu"
    net = write_network(folder, FEATURE_BRANCHES, FEATURE_NODES, dx=50.0)
    m1 = net.network._mesh1d
    m1.network1d_branch_order = np.array([FEATURE_ORDERS[str(b)] for b in m1.network1d_branch_id], dtype=np.int32)
    fm.geometry.netfile = net
    defs = m.CrossDefModel(definition=[
        m.ZWRiverCrsDef(id="river", numlevels=4, levels=[0.0, 0.5, 1.5, 3.0], flowwidths=[8.0, 12.0, 30.0, 40.0],
                        totalwidths=[8.0, 14.0, 40.0, 60.0], mainwidth=12.0, fp1width=28.0, fp2width=0.0,
                        frictionids=["Main", "Grass"], leveecrestLevel=0.9, leveebaselevel=0.9, leveeflowarea=6.0,
                        leveetotalrea=15.0),
        m.ZWCrsDef(id="plain", numlevels=3, levels=[0.0, 1.0, 3.0], flowwidths=[6.0, 10.0, 14.0], frictionid="Main"),
        m.ZWCrsDef(id="narrowing", numlevels=3, levels=[0.0, 1.0, 2.5], flowwidths=[4.0, 6.0, 5.0],
                   totalwidths=[4.0, 8.0, 9.0], frictionid="Grass"),
    ])
    defs.filepath = Path("crsdef.ini")
    locs = m.CrossLocModel(crosssection=[
        m.CrossSection(id=f"{b}_{k}", branchid=b, chainage=c, shift=z, definitionid=d)
        for b, items in FEATURE_SECTIONS.items() for k, (c, d, z) in enumerate(items)])
    locs.filepath = Path("crsloc.ini")
    fm.geometry.crossdeffile, fm.geometry.crosslocfile = defs, locs
    fm.geometry.frictfile = feature_frictions(discharge_dependent=discharge_dependent)
    OneDFieldModel(global_=OneDFieldGlobal(quantity="waterlevel", unit="m", value=1.0),
                   branch=[OneDFieldBranch(branchid="b1", numlocations=2, chainage=[0.0, 1000.0],
                                           values=[1.6, 1.2])]).save(folder / "level.ini")
    ini = IniFieldModel(initial=[InitialField(quantity="waterlevel", datafile=DiskOnlyFileModel(filepath=Path(
        "level.ini")), datafiletype="1dField")])
    ini.filepath = Path("initialFields.ini")
    fm.geometry.inifieldfile = ini
    bc = ForcingModel(forcing=[
        Constant(name="A", function="constant", quantityunitpair=[QuantityUnitPair(quantity="dischargebnd",
                                                                                   unit="m3/s")], datablock=[[6.0]]),
        Constant(name="E", function="constant", quantityunitpair=[QuantityUnitPair(quantity="dischargebnd",
                                                                                   unit="m3/s")], datablock=[[-1.0]]),
        Constant(name="D", function="constant", quantityunitpair=[QuantityUnitPair(quantity="waterlevelbnd",
                                                                                   unit="m")], datablock=[[0.9]]),
    ])
    bc.filepath = Path("boundaries.bc")
    ext = ExtModel(boundary=[Boundary(quantity="dischargebnd", nodeid="A", forcingfile=bc),
                             Boundary(quantity="dischargebnd", nodeid="E", forcingfile=bc),
                             Boundary(quantity="waterlevelbnd", nodeid="D", forcingfile=bc)])
    ext.filepath = Path("forcing.ext")
    fm.external_forcing.extforcefilenew = ext
    obs = ObservationPointModel(observationpoint=[
        ObservationPoint(name="obs_b1", branchid="b1", chainage=600.0),
        ObservationPoint(name="obs_b2", branchid="b2", chainage=300.0),
        ObservationPoint(name="obs_b3", branchid="b3", chainage=400.0)])
    obs.filepath = Path("obs.ini")
    fm.output.obsfile = [obs]
    fm.output.hisinterval = [600.0, 0.0, 0.0]
    fm.time.refdate = REFDATE
    fm.time.tunit = "S"
    fm.time.tstart = 0.0
    fm.time.tstop = 6 * 3600.0
    fm.time.dtmax = 60.0
    fm.physics.uniffricttype = 1
    fm.physics.uniffrictcoef1d = 0.025
    fm.geometry.dxdoubleat1dendnodes = False
    fm.save(recurse=True)
    return fm.filepath


def write_uniform_model(folder: Path, *, q: float, slope: float, width: float, depth: float,
                        strickler: tuple[float, float], length: float = 4000.0, dx: float = 25.0) -> Path:
    """One sloping rectangular branch whose friction depends on the water level; returns the MDU path.

    The branch ``B`` (``up`` → ``down``, ``length`` m, bed from ``slope · length`` m AD down to 0) carries a
    rectangle ``width`` m wide of friction group ``Bed`` (Chézy 30), which on ``B`` takes a Strickler coefficient
    from a ``functionType = waterLevel`` table at its two ends: k = a + b (z - z_b) with ``strickler = (a, b)``,
    z the water level and z_b the bed level at the end. Interpolated in chainage and level as D-Flow FM does, that is
    k = a + b h at every place (h the depth). A constant discharge ``q`` enters at ``up``; ``down`` is held at
    ``depth`` m AD (its bed is 0), the initial depth is ``depth``, and observation point ``mid`` lies halfway.
    Calculation points every ``dx`` m.
    """
    from hydrolib.core.base.models import DiskOnlyFileModel
    from hydrolib.core.dflowfm.bc.models import Constant, ForcingModel, QuantityUnitPair
    from hydrolib.core.dflowfm.crosssection import models as m
    from hydrolib.core.dflowfm.ext.models import Boundary, ExtModel
    from hydrolib.core.dflowfm.friction.models import FrictBranch, FrictGlobal, FrictionModel
    from hydrolib.core.dflowfm.inifield.models import IniFieldModel, InitialField
    from hydrolib.core.dflowfm.mdu.models import FMModel
    from hydrolib.core.dflowfm.obs.models import ObservationPoint, ObservationPointModel
    from hydrolib.core.dflowfm.onedfield.models import OneDFieldGlobal, OneDFieldModel

    folder.mkdir(parents=True, exist_ok=True)
    fm = FMModel()
    fm.filepath = folder / "uniform.mdu"
    fm.geometry.netfile = write_network(folder, {"B": ("up", "down")}, {"up": (0.0, 0.0), "down": (length, 0.0)},
                                        dx=dx)
    top = slope * length
    defs = m.CrossDefModel(definition=[m.RectangleCrsDef(id="rect", width=width, height=10.0, closed=False,
                                                         frictionid="Bed")])
    defs.filepath = Path("crsdef.ini")
    locs = m.CrossLocModel(crosssection=[
        m.CrossSection(id="B_up", branchid="B", chainage=0.0, shift=top, definitionid="rect"),
        m.CrossSection(id="B_down", branchid="B", chainage=length, shift=0.0, definitionid="rect")])
    locs.filepath = Path("crsloc.ini")
    fm.geometry.crossdeffile, fm.geometry.crosslocfile = defs, locs
    a, b = strickler
    levels = [0.0, top + 10.0]
    beds = [top, 0.0]  # at chainage 0 and length
    values = [a + b * (z - zb) for z in levels for zb in beds]  # numLocations values for each level in turn
    rough = FrictionModel(global_=[FrictGlobal(frictionid="Bed", frictiontype="Chezy", frictionvalue=30.0)],
                          branch=[FrictBranch(branchid="B", frictiontype="Strickler", functiontype="waterLevel",
                                              numlevels=2, levels=levels, numlocations=2, chainage=[0.0, length],
                                              frictionvalues=values)])
    rough.filepath = Path("roughness-Bed.ini")
    fm.geometry.frictfile = [rough]
    OneDFieldModel(global_=OneDFieldGlobal(quantity="waterdepth", unit="m", value=depth)).save(folder / "depth.ini")
    ini = IniFieldModel(initial=[InitialField(quantity="waterdepth", datafile=DiskOnlyFileModel(filepath=Path(
        "depth.ini")), datafiletype="1dField")])
    ini.filepath = Path("initialFields.ini")
    fm.geometry.inifieldfile = ini
    bc = ForcingModel(forcing=[
        Constant(name="up", function="constant", quantityunitpair=[QuantityUnitPair(quantity="dischargebnd",
                                                                                    unit="m3/s")], datablock=[[q]]),
        Constant(name="down", function="constant", quantityunitpair=[QuantityUnitPair(quantity="waterlevelbnd",
                                                                                      unit="m")],
                 datablock=[[depth]])])
    bc.filepath = Path("boundaries.bc")
    ext = ExtModel(boundary=[Boundary(quantity="dischargebnd", nodeid="up", forcingfile=bc),
                             Boundary(quantity="waterlevelbnd", nodeid="down", forcingfile=bc)])
    ext.filepath = Path("forcing.ext")
    fm.external_forcing.extforcefilenew = ext
    obs = ObservationPointModel(observationpoint=[ObservationPoint(name="mid", branchid="B", chainage=length / 2)])
    obs.filepath = Path("obs.ini")
    fm.output.obsfile = [obs]
    fm.output.hisinterval = [3600.0, 0.0, 0.0]
    fm.time.refdate = REFDATE
    fm.time.tunit = "S"
    fm.time.tstart = 0.0
    fm.time.tstop = 36 * 3600.0
    fm.time.dtmax = 120.0
    fm.geometry.dxdoubleat1dendnodes = False
    fm.save(recurse=True)
    return fm.filepath
