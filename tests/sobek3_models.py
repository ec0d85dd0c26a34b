"""A small SOBEK 3 model written as its INI files, for the tests of the SOBEK 3 import.

Every kind of object the import reads appears: a network of five nodes and four branches (``A -(b1)- B -(b2)- C
-(b3)- D`` with a side branch ``B -(b4)- E``, 1 km each, grid points every 100 m; b1 and b2 of order 1), the
cross-section types tabulated (main channel, floodplain, a summer dike, a flow width that narrows), rectangle,
trapezium, circle, yz and egg, roughness of every function type (constant along a branch in a law of its own,
a water-level table, a discharge table), every structure type, boundaries of each kind (a discharge series,
a constant level, a Q(h) table with SOBEK 3's negative outflow), laterals on branches and a node,
observation points, an initial level field and a retention area. The numbers written here are the reference
the tests compare the case with.

``write_model(folder, **replace)`` writes the files; ``replace`` maps a file name to ``(old, new)`` text
replacements, so that a test can break one value and check the error names its file, line and key.
"""

from __future__ import annotations

from pathlib import Path

NODES = {"A": (0.0, 0.0), "B": (1000.0, 0.0), "C": (2000.0, 0.0), "D": (3000.0, 0.0), "E": (1000.0, 1000.0)}
BRANCHES = {"b1": ("A", "B", 1), "b2": ("B", "C", 1), "b3": ("C", "D", -1), "b4": ("B", "E", -1)}

MD1D = """[General]
    majorVersion          = 1
    fileType              = modelDef

[Files]
    networkFile           = NetworkDefinition.ini# the network
    crossLocFile          = CrossSectionLocations.ini
    crossDefFile          = CrossSectionDefinitions.ini
    structureFile         = Structures.ini
    obsPointsFile         = ObservationPoints.ini
    initialWaterLevelFile = InitialWaterLevel.ini
    initialWaterDepthFile = InitialWaterDepth.ini
    roughnessFile         = roughness-Main.ini;roughness-FloodPlain1.ini
    boundLocFile          = BoundaryLocations.ini
    latDischargeLocFile   = LateralDischargeLocations.ini
    boundCondFile         = BoundaryConditions.bc
    retentionFile         = Retention.ini
    logFile               = sobek.log

[GlobalValues]
    InitialWaterLevel     = 0.000
    InitialWaterDepth     = 0.500
    InitialDischarge      = 0.000

[Time]
    StartTime             = 2020-01-01 00:00:00
    StopTime              = 2020-01-02 00:00:00
    TimeStep              = 60.000
    OutTimeStepGridPoints = 600.000

[NumericalParameters]
    Theta                 = 1.0
    MaxIterations         = 8
    MinimumSurfaceinNode  = 0.1
    CourantNumber         = 0.7

[AdvancedOptions]
    TransitionHeightSD    = 0.4
"""


def _network() -> str:
    lines = ["[General]", "    majorVersion = 1", "    fileType = network", ""]
    for name, (x, y) in NODES.items():
        lines += ["[Node]", f"    id = {name}", f"    x = {x:.3f}", f"    y = {y:.3f}", ""]
    for name, (a, b, order) in BRANCHES.items():
        (xa, ya), (xb, yb) = NODES[a], NODES[b]
        offsets = [100.0 * k for k in range(11)]
        lines += ["[Branch]", f"    id = {name}", f"    fromNode = {a}", f"    toNode = {b}", f"    order = {order}",
                  f"    geometry = LINESTRING ({xa:g} {ya:g} 0, {xb:g} {yb:g} 0)",
                  f"    gridPointsCount = {len(offsets)}",
                  "    gridPointOffsets = " + " ".join(f"{o:.3f}" for o in offsets),
                  "    gridPointIds = " + ";".join(f"{name}_{o:.3f}" for o in offsets), ""]
    return "\n".join(lines)


CROSS_DEFS = """[General]
    majorVersion          = 1
    fileType              = crossDef

[Definition]
    id                    = river
    type                  = tabulated
    thalweg               = 0.000
    numLevels             = 5
    levels                = -1.0 0.5 0.6 2.0 4.0
    flowWidths            = 6.0 10.0 30.0 24.0 40.0
    totalWidths           = 6.0 12.0 36.0 40.0 50.0
    sd_crest              = 1.2
    sd_flowArea           = 5.0
    sd_totalArea          = 8.0
    sd_baseLevel          = 0.7
    main                  = 10.0
    floodPlain1           = 35.0
    groundlayerUsed       = 0
    groundlayer           = 0.000

[Definition]
    id                    = rect
    type                  = rectangle
    width                 = 5.0
    height                = 3.0
    closed                = 0

[Definition]
    id                    = trap
    type                  = trapezium
    bottomWidth           = 4.0
    maximumFlowWidth      = 10.0
    slope                 = 1.5

[Definition]
    id                    = pipe
    type                  = circle
    diameter              = 1.0

[Definition]
    id                    = yz1
    type                  = yz
    yzCount               = 6
    yValues               = 0 2 4 6 8 10
    zValues               = 3 1 0 0 1 3
    sectionCount          = 2
    roughnessNames        = Main;FloodPlain1
    roughnessPositions    = 0 5 10

[Definition]
    id                    = egg1
    type                  = egg
    diameter              = 1.0

[Definition]
    id                    = unused
    type                  = rectangle
    width                 = 2.0
"""

CROSS_LOCS = """[General]
    majorVersion          = 1
    fileType              = crossLoc

[CrossSection]
    id                    = cs_b1_up
    branchid              = b1
    chainage              = 100.000
    shift                 = 0.000
    definition            = river

[CrossSection]
    id                    = cs_b1_down
    branchid              = b1
    chainage              = 900.000
    shift                 = -0.500
    definition            = river

[CrossSection]
    id                    = cs_b2
    branchid              = b2
    chainage              = 500.000
    shift                 = -2.0
    definition            = yz1

[CrossSection]
    id                    = cs_b3_up
    branchid              = b3
    chainage              = 0.000
    shift                 = -2.1
    definition            = trap

[CrossSection]
    id                    = cs_b3_down
    branchid              = b3
    chainage              = 1000.000
    shift                 = -2.3
    definition            = rect

[CrossSection]
    id                    = cs_b4
    branchid              = b4
    chainage              = 500.000
    shift                 = -1.5
    definition            = rect

[CrossSection]
    id                    = cs_egg
    branchid              = b4
    chainage              = 600.000
    shift                 = -1.5
    definition            = egg1
"""

ROUGH_MAIN = """[General]
    majorVersion          = 1
    fileType              = roughness

[Content]
    sectionId             = Main
    flowDirection         = False
    interpolate           = 1
    globalType            = 1
    globalValue           = 45.000

[BranchProperties]
    branchId              = b1
    roughnessType         = 1
    functionType          = 2
    numLevels             = 3
    levels                = -1.0 1.0 3.0

[Definition]
    branchId              = b1
    chainage              = 0.000
    values                = 30.0 40.0 50.0

[Definition]
    branchId              = b1
    chainage              = 1000.000
    values                = 32.0 42.0 52.0

[BranchProperties]
    branchId              = b2
    roughnessType         = 4
    functionType          = 0

[Definition]
    branchId              = b2
    chainage              = 0.000
    value                 = 0.030

[Definition]
    branchId              = b2
    chainage              = 1000.000
    value                 = 0.040

[BranchProperties]
    branchId              = b3
    roughnessType         = 5
    functionType          = 0

[Definition]
    branchId              = b3
    chainage              = 0.000
    value                 = 0.064

[BranchProperties]
    branchId              = b4
    roughnessType         = 1
    functionType          = 1
    numLevels             = 2
    levels                = 0.0 10.0

[Definition]
    branchId              = b4
    chainage              = 0.000
    values                = 40.0 50.0
"""

ROUGH_FP1 = """[General]
    majorVersion          = 1
    fileType              = roughness

[Content]
    sectionId             = FloodPlain1
    flowDirection         = False
    interpolate           = 1
    globalType            = 6
    globalValue           = 20.000
"""

STRUCTURES = """[General]
    majorVersion          = 1
    fileType              = structure

[Structure]
    id                    = weir1
    branchid              = b3
    chainage              = 450.000
    type                  = weir
    crestLevel            = -1.0
    crestWidth            = 3.0
    dischargeCoeff        = 1.1
    latDisCoeff           = 0.9
    allowedFlowDir        = 0

[Structure]
    id                    = culvert1
    branchid              = b3
    chainage              = 250.000
    type                  = culvert
    csDefId               = pipe
    leftLevel             = -1.9
    rightLevel            = -1.95
    length                = 12.0
    inletLossCoeff        = 0.6
    outletLossCoeff       = 0.9
    bedFrictionType       = 4
    bedFriction           = 0.014
    groundFrictionType    = 1
    groundFriction        = 45.0
    allowedFlowDir        = 1
    valveOnOff            = 0

[Structure]
    id                    = orifice1
    branchid              = b4
    chainage              = 250.000
    type                  = orifice
    crestLevel            = -1.2
    crestWidth            = 2.0
    openLevel             = -0.5
    contractionCoeff      = 0.63
    latContrCoeff         = 0.9
    allowedFlowDir        = 2
    useLimitFlowPos       = 1
    limitFlowPos          = 4.0

[Structure]
    id                    = pump1
    branchid              = b4
    chainage              = 650.000
    type                  = pump
    direction             = 1
    nrStages              = 1
    capacity              = 0.5
    startLevelSuctionSide = 0.2
    stopLevelSuctionSide  = -0.3

[Structure]
    id                    = uweir1
    branchid              = b2
    chainage              = 850.000
    type                  = universalWeir
    crestLevel            = -1.5
    dischargeCoeff        = 0.85
    allowedFlowDir        = 0
    levelsCount           = 4
    yValues               = 0 1 3 4
    zValues               = -0.8 -1.5 -1.5 -0.8

[Structure]
    id                    = bridge1
    branchid              = b3
    chainage              = 750.000
    type                  = bridge
    csDefId               = rect
    bedLevel              = -2.2
    length                = 10.0
    inletLossCoeff        = 0.3
    outletLossCoeff       = 0.8
    bedFrictionType       = 6
    bedFriction           = 40.0
    groundFrictionType    = 1
    groundFriction        = 45.0
    allowedFlowDir        = 0

[Structure]
    id                    = general1
    branchid              = b2
    chainage              = 150.000
    type                  = generalStructure
"""

OBS = """[General]
    majorVersion          = 1
    fileType              = obsPoints

[ObservationPoint]
    id                    = obs1
    branchid              = b1
    chainage              = 200.000

[ObservationPoint]
    id                    = obs.2
    branchid              = b3
    chainage              = 600.000

[ObservationPoint]
    id                    = nowhere
    branchid              = b9
    chainage              = 10.000
"""

INITIAL = """[General]
    majorVersion          = 1
    fileType              = spatialData

[Content]
    quantity              = InitialWaterLevel
    interpolate           = 1

[Definition]
    branchId              = b1
    chainage              = 0.000
    value                 = 1.0

[Definition]
    branchId              = b1
    chainage              = 1000.000
    value                 = 0.5
"""

BOUND_LOCS = """[General]
    majorVersion          = 1
    fileType              = boundLocs

[Boundary]
    nodeId                = A
    type                  = 2

[Boundary]
    nodeId                = D
    type                  = 1

[Boundary]
    nodeId                = E
    type                  = 1
"""

LAT_LOCS = """[General]
    majorVersion          = 1
    fileType              = latLocs

[LateralDischarge]
    id                    = lat1
    branchid              = b1
    chainage              = 300.000

[LateralDischarge]
    id                    = lat2
    branchid              = b2
    chainage              = 600.000
    length                = 200.000

[LateralDischarge]
    id                    = lat3
    nodeId                = C
"""

BC = """[General]
    majorVersion          = 1
    fileType              = boundConds

[Boundary]
    name                  = A
    function              = timeseries
    time-interpolation    = linear-extrapolate
    quantity              = time
    unit                  = minutes since 2020-01-01 00:00:00
    quantity              = water_discharge
    unit                  = m³/s
    0 2.0
    360 6.0
    1440 3.0

[Boundary]
    name                  = D
    function              = qhtable
    time-interpolation    = linear-extrapolate
    quantity              = water_level
    unit                  = m
    quantity              = water_discharge
    unit                  = m³/s
    -1.5 -1.0
    -1.0 -4.0
    0.5 -20.0

[Boundary]
    name                  = E
    function              = constant
    quantity              = water_level
    unit                  = m
    0.4

[LateralDischarge]
    name                  = lat1
    function              = constant
    quantity              = water_discharge
    unit                  = m³/s
    0.2

[LateralDischarge]
    name                  = lat2
    function              = timeseries
    time-interpolation    = block-from
    quantity              = time
    unit                  = hours since 2020-01-01 00:00:00
    quantity              = water_discharge
    unit                  = m³/s
    0 0.1
    12 0.3

[LateralDischarge]
    name                  = lat3
    function              = constant
    quantity              = water_discharge
    unit                  = m³/s
    -0.05

[Boundary]
    name                  = model_wide
    function              = timeseries
    quantity              = time
    unit                  = minutes since 2020-01-01 00:00:00
    quantity              = wind_speed
    unit                  = m/s
    0 0
"""

RETENTION = """[General]
    majorVersion          = 1
    fileType              = retentions

[Retention]
    id                    = pond
    nodeId                = C
    numLevels             = 3
    levels                = -1.0 0.0 1.0
    storageArea           = 50.0 100.0 80.0
"""

FILES = {
    "Flow1D.md1d": MD1D,
    "CrossSectionDefinitions.ini": CROSS_DEFS,
    "CrossSectionLocations.ini": CROSS_LOCS,
    "roughness-Main.ini": ROUGH_MAIN,
    "roughness-FloodPlain1.ini": ROUGH_FP1,
    "Structures.ini": STRUCTURES,
    "ObservationPoints.ini": OBS,
    "InitialWaterLevel.ini": INITIAL,
    "BoundaryLocations.ini": BOUND_LOCS,
    "LateralDischargeLocations.ini": LAT_LOCS,
    "BoundaryConditions.bc": BC,
    "Retention.ini": RETENTION,
}


def write_model(folder: Path, **replace: tuple[str, str]) -> Path:
    """Write the model into ``folder``; returns the md1d path.

    ``replace`` maps a file name, with ``.`` and ``-`` written as ``_`` (``Structures_ini``), to an (old, new)
    text replacement made in that file (the old text must be there).
    """
    folder.mkdir(parents=True, exist_ok=True)
    files = {**FILES, "NetworkDefinition.ini": _network()}
    for key, (old, new) in replace.items():
        name = next(n for n in files if n.replace(".", "_").replace("-", "_") == key)
        assert old in files[name], (name, old)
        files[name] = files[name].replace(old, new, 1)
    for name, text in files.items():
        (folder / name).write_text(text.replace("\n", "\r\n"), encoding="utf-8")
    return folder / "Flow1D.md1d"
