"""The river network as validated data (layer 2): nodes, branches, profiles, structures, forcing, stations.

These pydantic models are both the in-memory network description and the schema of the network
part of ``case.toml`` (see ``docs/case-format.md``). One module per kind of object, each with its
own checks:

- :mod:`~rivercal.network.friction` — the friction law and its plausible ranges, friction groups;
- :mod:`~rivercal.network.profiles` — cross-section shapes (rectangular, trapezoidal, circular, ZW, YZ);
- :mod:`~rivercal.network.nodes` — connection nodes and their storage;
- :mod:`~rivercal.network.branches` — branches and the cross-sections along them;
- :mod:`~rivercal.network.structures` — weirs, universal weirs, orifices, culverts, bridges and pumps;
- :mod:`~rivercal.network.forcing` — boundaries, laterals and the series they read;
- :mod:`~rivercal.network.stations` — observation stations;
- :mod:`~rivercal.network.topology` — the :class:`Network` and the rules that need all of it
  (unknown ids, a crest below the bed).

Field-level rules (positive widths, monotone tables, finite numbers) are checked by the objects
themselves. Every rule that fails raises :class:`~rivercal.errors.FieldProblem`, a ``ValueError``
that carries the path of the offending field relative to the object that raised it
(``cross_sections[1].chainage``), so that the case loader can report the full path
(``branches[2].cross_sections[1].chainage``). No numerics beyond the bed level along a branch, no I/O.

Conventions
-----------
Levels are in m above the vertical datum (m AD); depths, widths, lengths and chainages in m;
discharges in m³/s; areas in m². The positive flow direction of a branch runs from its
``from_node`` (chainage 0) to its ``to_node`` (chainage = ``length``). Numbers must be finite
(``nan`` and ``inf`` are rejected) and written as numbers, not as quoted text.
"""

from rivercal.errors import FieldProblem
from rivercal.network._base import (
    MAX_DISCHARGE,
    MAX_LEVEL,
    MAX_SIZE,
    MIN_SIZE,
    Discharge,
    Identifier,
    Level,
    Real,
    Size,
)
from rivercal.network.branches import MAX_POINTS_PER_BRANCH, Branch, CrossSection, InitialLevels
from rivercal.network.forcing import Boundary, Lateral, RatingTable, SeriesRef
from rivercal.network.friction import FRICTION_RANGES, BranchFriction, Friction, FrictionGroup
from rivercal.network.nodes import Node, StorageTable
from rivercal.network.profiles import (
    CircularProfile,
    Profile,
    RectangularProfile,
    SummerDike,
    TrapezoidalProfile,
    YZProfile,
    ZWProfile,
    profile_sections,
)
from rivercal.network.stations import Station
from rivercal.network.structures import Bridge, Culvert, Orifice, Pump, UniversalWeir, Weir
from rivercal.network.topology import STRUCTURE_TABLES, Network

__all__ = [
    "FRICTION_RANGES",
    "MAX_DISCHARGE",
    "MAX_LEVEL",
    "MAX_POINTS_PER_BRANCH",
    "MAX_SIZE",
    "MIN_SIZE",
    "STRUCTURE_TABLES",
    "Boundary",
    "Branch",
    "BranchFriction",
    "Bridge",
    "CircularProfile",
    "CrossSection",
    "Culvert",
    "Discharge",
    "FieldProblem",
    "Friction",
    "FrictionGroup",
    "Identifier",
    "InitialLevels",
    "Lateral",
    "Level",
    "Network",
    "Node",
    "Orifice",
    "Profile",
    "Pump",
    "RatingTable",
    "Real",
    "RectangularProfile",
    "SeriesRef",
    "Size",
    "Station",
    "StorageTable",
    "SummerDike",
    "TrapezoidalProfile",
    "UniversalWeir",
    "Weir",
    "YZProfile",
    "ZWProfile",
    "profile_sections",
]
