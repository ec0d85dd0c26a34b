"""``import_mascaret``: a Mascaret model (``.xcas`` and the files it names) → a case folder with ``import.md``.

What is converted, and how (each object is accounted for in ``import.md``; the facts about Mascaret's files
are from TELEMAC-Mascaret's own readers, ``sources/mascaret/Pretrait``):

- **reaches** (``listeBranches``): one branch per reach, from its start to its end abscissa; the reach's
  extremities meet at the **nodes** of ``listeNoeuds`` (confluences) or are free ends (``extrLibres``).
- **profiles** (``.geo``): one ``yz`` profile per surveyed profile, placed at its abscissa at its lowest level,
  with ``lumped`` conveyance per bed (Mascaret computes A and P per bed, not per piece); a profile with a major
  bed (``T`` points) has three friction sections (major, minor, major).
- **friction** (``parametresCalage/frottement``): one friction group per zone and bed
  (``zone<k>_minor``, ``zone<k>_major``), the law of the zone (Strickler, Chézy; Colebrook as White-Colebrook),
  assigned to every profile whose abscissa lies in the zone; a ``[[parameters]]`` entry per group, so the zones
  are calibration targets (``friction:group:zone1_minor``).
- **computational grid** (``parametresPlanimetrageMaillage/maillage``): the calculation points Mascaret
  computes on (methods 1, 2, 3 and 5, as its ``MAILLER`` lays them out) become each branch's ``points``.
- **boundaries** (``extrLibres``): discharge, level, ratings (Z = f(Q), Q = f(Z)), free outflow (a critical
  outfall), normal depth (a rating from the end profile, the zone's friction and the bed slope).
- **laterals** (``debitsApports``): point inflows; an inflow over a length (Mascaret's linear inflow, m³/s per
  m) becomes one point inflow per calculation point of the stretch, as Mascaret distributes it.
- **laws** (``.loi``): time series into ``forcing.csv`` (a constant law becomes a constant value), times from
  ``--origin`` (Mascaret's time 0).
- **time and numerics** (``parametresTemporels``): period, time step and output interval; the kernel and its
  numerical options are accounted for as approximations (rivercal's engine discretises the same equations
  with its own scheme).
- **stations**: Mascaret's output sites (``stockage``) or, when it stores every section, one per profile; and
  any stations given with the import (gauges).

Weirs and other singularities, lateral weirs, storage areas (``casiers``), storage zones, head losses, dam
breaks and tracers are refused (with their names); the hydraulic ones block the import unless partial imports
are allowed.
"""

from __future__ import annotations

import logging
import math
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError
from rivercal.io.ledger import conclude
from rivercal.io.mascaret._files import LAW_NAMES, Geometry, GeoProfile, Law, read_geometry, read_law
from rivercal.io.mascaret._ledger import Ledger
from rivercal.io.mascaret._xcas import Element, Xcas, read_xcas
from rivercal.network import FRICTION_RANGES

__all__ = ["ImportOptions", "ImportResult", "StationSpec", "import_mascaret"]

log = logging.getLogger(__name__)

#: Mascaret's kernels (``<code>``).
KERNELS = {1: "SARAP (steady, sub- and supercritical)", 2: "REZODT (unsteady, subcritical)",
           3: "MASCARET (unsteady, transcritical)"}
#: Mascaret's friction laws (``parametresCalage/frottement/loi``) → case law.
FRICTION_LAWS = {1: "strickler", 2: "chezy", 3: "white-colebrook"}
#: Mascaret's boundary types (``extrLibres/typeCond``).
BOUNDARY_TYPES = {1: "discharge imposed", 2: "level imposed", 3: "rating Z = f(Q)", 4: "rating Q = f(Z)",
                  5: "downstream level as a function of the upstream discharge", 6: "free outflow",
                  7: "normal depth", 8: "level and discharge imposed"}
FORCING_FILE = "forcing.csv"
_BAD = re.compile(r"[^A-Za-z0-9_.\-]")


@dataclass(frozen=True)
class StationSpec:
    """A station to add to the imported case (a gauge).

    Attributes
    ----------
    id
        Station id (letters, digits, ``_``, ``-``; no ``.``).
    reach
        The Mascaret reach: its name in the geometry file or its number (1-based).
    abscissa
        Position along the reach in Mascaret's abscissa, m.
    file, line
        Where the station was given (a station list), for messages.
    """

    id: str
    reach: str
    abscissa: float
    file: str | None = None
    line: int | None = None


@dataclass(frozen=True)
class ImportOptions:
    """Options of an import.

    Attributes
    ----------
    allow_partial
        Write the case even when objects that change the hydraulics were refused (they are left out).
    origin
        The date and time of Mascaret's time 0 (UTC): Mascaret counts time in seconds, a case in dates.
    dt
        Time step of the case, s (default: Mascaret's ``pasTemps``).
    output_interval
        Output interval, s (default: Mascaret's storage interval, ``pasStock`` steps).
    hours
        Length of the simulated period, h (default: Mascaret's, from its stopping criterion).
    cross_sections
        ``interpolated`` (Mascaret's way: each calculation point between two profiles takes the profile
        interpolated between them) or ``nearest``.
    stations
        Stations to add (gauges), besides Mascaret's own output sites.
    spinup
        Spin-up before the period, h (the case's ``initial.spinup``).
    initial_depth
        Initial depth of the cold start, m (the case's ``initial.depth``).
    """

    allow_partial: bool = False
    origin: str = "2000-01-01T00:00:00Z"
    dt: float | None = None
    output_interval: float | None = None
    hours: float | None = None
    cross_sections: str = "interpolated"
    stations: tuple[StationSpec, ...] = ()
    spinup: float = 0.0
    initial_depth: float = 0.5


@dataclass(frozen=True)
class ImportResult:
    """What an import produced.

    Attributes
    ----------
    folder
        The case folder (``case.toml``, ``forcing.csv``, ``import.md``).
    summary
        Counts: branches, points, profiles, friction groups, boundaries, laterals, stations, approximated,
        refused; and the case period.
    ledger
        The full account (also in ``import.md``).
    """

    folder: Path
    summary: dict
    ledger: Ledger


# -- the model as read ----------------------------------------------------------------------------------------


@dataclass
class _Reach:
    number: int
    name: str
    branch: str
    start: float
    end: float
    ext_start: int
    ext_end: int
    profiles: list[GeoProfile]
    profile_ids: list[tuple[GeoProfile, str]] = field(default_factory=list)
    points: list[float] | None = None
    cross_sections: list[dict] = field(default_factory=list)
    node_start: str = ""
    node_end: str = ""

    @property
    def length(self) -> float:
        return self.end - self.start

    def chainage(self, abscissa: float) -> float:
        return abscissa - self.start


class _Ids:
    """Case ids made from Mascaret names (letters, digits, ``_ - .``; unique per kind; renames recorded)."""

    def __init__(self, ledger: Ledger):
        self.ledger = ledger
        self.used: dict[str, set[str]] = defaultdict(set)

    def make(self, kind: str, name: str, *, no_dot: bool = False) -> str:
        new = _BAD.sub("_", name.strip()) or "unnamed"
        if no_dot:
            new = new.replace(".", "_")
        new = new[:60]
        base, k = new, 2
        while new in self.used[kind]:
            new = f"{base[:56]}_{k}"
            k += 1
        self.used[kind].add(new)
        if new != name:
            self.ledger.renamed.setdefault(kind, {})[name] = new
        return new


class _Converter:
    def __init__(self, xcas: Xcas, options: ImportOptions):
        self.x = xcas
        self.o = options
        self.ledger = Ledger()
        self.ids = _Ids(self.ledger)
        self.case: dict = {}
        self.series: dict[str, pd.Series] = {}
        self.reaches: list[_Reach] = []
        self.laws: list[dict] = []
        self.origin = pd.Timestamp(options.origin)
        if self.origin.tzinfo is None:
            self.origin = self.origin.tz_localize("UTC")
        self.origin = self.origin.tz_convert("UTC")

    # -- helpers --------------------------------------------------------------------------------------

    def file(self, name: str, element: Element | None, path: str) -> Path:
        """A file the case file names, relative to its folder; an error naming the element when it is missing."""
        p = Path(name.strip())
        if not p.is_absolute():
            p = self.x.folder / p
        if not p.is_file():
            raise self.x.error(element, path, f"the file {name.strip()!r} named here does not exist ({p})")
        return p

    def reach_of(self, number: int, element: Element | None, path: str) -> _Reach:
        if not 1 <= number <= len(self.reaches):
            raise self.x.error(element, path, f"reach number {number} does not exist (the model has "
                                              f"{len(self.reaches)} reach(es))")
        return self.reaches[number - 1]

    def inside(self, reach: _Reach, abscissa: float, element: Element | None, path: str, what: str) -> float:
        """Chainage of an abscissa of a reach, checked against the reach's extent."""
        tol = 1e-4
        if not reach.start - tol <= abscissa <= reach.end + tol:
            raise self.x.error(element, path, f"{what} at abscissa {abscissa:g} m lies outside reach {reach.name!r} "
                                              f"({reach.start:g} .. {reach.end:g} m)")
        return min(max(reach.chainage(abscissa), 0.0), reach.length)

    # -- the steps ------------------------------------------------------------------------------------

    def run(self) -> None:
        self.kernel()
        geometry = self.geometry()
        self.network(geometry)
        self.profiles_and_friction()
        self.mesh()
        self.laws_read()
        self.period_and_engine()
        self.boundaries()
        self.laterals()
        self.initial()
        self.stations()
        self.refusals()
        self.settings()

    def kernel(self) -> None:
        code = self.x.integer("parametresGeneraux/code", 3)
        self.code = code
        if code not in KERNELS:
            raise self.x.error(self.x.find("parametresGeneraux/code"), "parametresGeneraux/code",
                               f"kernel {code} is not one of Mascaret's kernels 1 (SARAP), 2 (REZODT), 3 (MASCARET)")
        steady = " A steady computation is reached by running the unsteady engine with the forcing held until the " \
                 "levels stop changing." if code == 1 else ""
        self.ledger.approximated("setting", "code", f"Mascaret's kernel {code}, {KERNELS[code]}: rivercal's engine "
                                 "solves the same De Saint-Venant equations on the staggered Delft scheme (implicit, "
                                 "upwind, sub- and supercritical flow)." + steady)

    def geometry(self) -> Geometry:
        path = "parametresGeometrieReseau/geometrie/fichier"
        element = self.x.find(path)
        if element is None or not element.text:
            raise self.x.error(self.x.find("parametresGeometrieReseau"), path, "no geometry file is named")
        fmt_path = "parametresGeometrieReseau/geometrie/format"
        fmt = self.x.integer(fmt_path, 2)
        if fmt != 2:
            raise self.x.error(self.x.find(fmt_path), fmt_path,
                               f"geometry format {fmt} (LIDO 2.0) is not read; only format 2 (the 'PROFIL' format "
                               "of LIDO 3.0) is: save the geometry in that format (FUDAA-Mascaret does)")
        geo = read_geometry(self.file(element.text, element, path))
        self.geo_path = geo.path
        self.ledger.exact("geometry file", geo.path.name, f"{len(geo.profiles)} profiles in "
                                                          f"{len(geo.reaches())} reach(es)")
        return geo

    def network(self, geo: Geometry) -> None:
        base = "parametresGeometrieReseau/listeBranches"
        n = self.x.integer(f"{base}/nb")
        groups = geo.reaches()
        if n != len(groups):
            raise self.x.error(self.x.find(f"{base}/nb"), f"{base}/nb",
                               f"{n} reach(es) here but {len(groups)} in the geometry file {geo.path.name}")
        starts = self.x.numbers(f"{base}/abscDebut", n)
        ends = self.x.numbers(f"{base}/abscFin", n)
        ext_start = self.x.integers(f"{base}/numExtremDebut", n)
        ext_end = self.x.integers(f"{base}/numExtremFin", n)
        for k, (name, profiles) in enumerate(groups):
            a, b = starts[k], ends[k]
            first, last = profiles[0].abscissa, profiles[-1].abscissa
            if not b > a:
                raise self.x.error(self.x.find(f"{base}/abscFin"), f"{base}/abscFin",
                                   f"reach {k + 1} ({name!r}) ends at {b:g} m, not after its start {a:g} m")
            if a < first - 1e-4 or b > last + 1e-4:  # Mascaret's own check (error 335)
                raise self.x.error(self.x.find(f"{base}/abscDebut"), f"{base}/abscDebut",
                                   f"reach {k + 1} ({name!r}) runs from {a:g} to {b:g} m, beyond its profiles "
                                   f"({first:g} .. {last:g} m in {geo.path.name})")
            branch = self.ids.make("branch", name)
            self.reaches.append(_Reach(k + 1, name, branch, a, b, ext_start[k], ext_end[k], profiles))
            self.ledger.exact("reach", name, f"branch {branch!r}, {b - a:g} m")
        # nodes: confluences group extremities; free extremities carry the boundaries
        node_of: dict[int, str] = {}
        nodes_el = self.x.find("parametresGeometrieReseau/listeNoeuds")
        n_nodes = self.x.integer("parametresGeometrieReseau/listeNoeuds/nb", 0)
        node_elements = nodes_el.descendants("noeud") if nodes_el is not None else []
        if n_nodes > len(node_elements):
            raise self.x.error(nodes_el, "parametresGeometrieReseau/listeNoeuds",
                               f"{n_nodes} node(s) announced, {len(node_elements)} given")
        for k, element in enumerate(node_elements[:n_nodes]):
            ext = [e for e in self.x.integers("num", within=element) if e > 0]
            node = self.ids.make("node", f"node{k + 1}")
            for e in ext:
                node_of[e] = node
            self.ledger.exact("node", f"node {k + 1}", f"confluence of extremities {', '.join(map(str, ext))}")
        free = "parametresGeometrieReseau/extrLibres"
        n_free = self.x.integer(f"{free}/nb", 0)
        self.free = {
            "ext": self.x.integers(f"{free}/numExtrem", n_free),
            "type": self.x.integers(f"{free}/typeCond", n_free),
            "law": self.x.integers(f"{free}/numLoi", n_free),
            "names": self.x.strings(f"{free}/noms"),
        }
        self.free_node: dict[int, str] = {}
        for i, e in enumerate(self.free["ext"]):
            name = self.free["names"][i] if i < len(self.free["names"]) else f"end{e}"
            if e in node_of:
                raise self.x.error(self.x.find(f"{free}/numExtrem"), f"{free}/numExtrem",
                                   f"extremity {e} is both a free end and part of a confluence")
            node_of[e] = self.ids.make("node", name)
            self.free_node[i] = node_of[e]
        nodes: dict[str, dict] = {}
        for r in self.reaches:
            for e in (r.ext_start, r.ext_end):
                if e not in node_of:
                    node_of[e] = self.ids.make("node", f"end{e}")
                    self.ledger.approximated("node", f"extremity {e}", "an extremity that is neither a free end nor "
                                             "at a confluence: a closed end of the case")
            r.node_start, r.node_end = node_of[r.ext_start], node_of[r.ext_end]
            if r.node_start == r.node_end:
                raise self.x.error(self.x.find(f"{base}/numExtremFin"), f"{base}/numExtremFin",
                                   f"reach {r.name!r} starts and ends at the same node")
            for node, p in ((r.node_start, r.profiles[0]), (r.node_end, r.profiles[-1])):
                entry = nodes.setdefault(node, {"id": node})
                if p.axis is not None and "x" not in entry:
                    entry["x"], entry["y"] = p.axis
        self.case["nodes"] = list(nodes.values())

    def profiles_and_friction(self) -> None:
        base = "parametresCalage/frottement"
        law_code = self.x.integer(f"{base}/loi", 1)
        law_path = f"{base}/loi"
        if law_code == 4:
            raise self.x.error(self.x.find(law_path), law_path, "Bazin's friction law (4) has no counterpart in a "
                                                                 "case (Strickler, Manning, Chézy, White-Colebrook)")
        if law_code not in FRICTION_LAWS:
            raise self.x.error(self.x.find(law_path), law_path, f"friction law {law_code} is not one of Mascaret's "
                               "laws 1 (Strickler), 2 (Chézy), 3 (Colebrook), 4 (Bazin)")
        law = FRICTION_LAWS[law_code]
        if law_code == 3:
            self.ledger.approximated("setting", "frottement/loi", "Colebrook's law: the case's White-Colebrook "
                                     "law (rough turbulent flow, roughness height in m)")
        n = self.x.integer(f"{base}/nbZone")
        if n < 1:
            raise self.x.error(self.x.find(f"{base}/nbZone"), f"{base}/nbZone", "at least one friction zone is needed")
        branches = self.x.integers(f"{base}/numBranche", n)
        starts = self.x.numbers(f"{base}/absDebZone", n)
        ends = self.x.numbers(f"{base}/absFinZone", n)
        minor = self.x.numbers(f"{base}/coefLitMin", n)
        major = self.x.numbers(f"{base}/coefLitMaj", n)
        low, high, unit = FRICTION_RANGES[law]
        zones = []
        for k in range(n):
            reach = self.reach_of(branches[k], self.x.find(f"{base}/numBranche"), f"{base}/numBranche")
            for value, bed, tag in ((minor[k], "minor", "coefLitMin"), (major[k], "major", "coefLitMaj")):
                if not low <= value <= high:
                    raise self.x.error(self.x.find(f"{base}/{tag}"), f"{base}/{tag}",
                                       f"the {bed}-bed coefficient of zone {k + 1}, {value:g} {unit}, is outside the "
                                       f"plausible range {low:g}-{high:g} {unit} of the {law} law")
            for a, what in ((starts[k], "absDebZone"), (ends[k], "absFinZone")):
                self.inside(reach, a, self.x.find(f"{base}/{what}"), f"{base}/{what}", f"friction zone {k + 1}")
            zones.append({"k": k + 1, "reach": reach, "start": starts[k], "end": ends[k], "minor": minor[k],
                          "major": major[k]})
        interpolate = self.x.boolean("parametresModelePhysique/interpolLinStrickler", False)
        groups: dict[str, dict] = {}
        parameters: list[dict] = []
        used_zone: set[int] = set()
        profiles: list[dict] = []
        in_gap: list[str] = []
        for reach in self.reaches:
            cross_sections = []
            mine = [z for z in zones if z["reach"] is reach]
            for p in reach.profiles:
                zone = _zone_of(p.abscissa, mine)
                if zone is None:
                    if not mine or p.abscissa < min(z["start"] for z in mine):
                        self.ledger.refused("profile", p.name, f"no friction zone covers abscissa {p.abscissa:g} m of "
                                            f"reach {reach.name!r}")
                        continue
                    zone = max((z for z in mine if z["end"] <= p.abscissa), key=lambda z: z["end"])
                    in_gap.append(p.name)
                converted = self._profile(p, reach, zone, law, groups)
                if converted is None:
                    continue
                used_zone.add(zone["k"])
                profiles.append(converted)
                cross_sections.append({"chainage": reach.chainage(p.abscissa), "profile": converted["id"],
                                       "bed_level": p.bed_level})
            reach.cross_sections = cross_sections
        if in_gap:
            how = ("linearly interpolated by Mascaret (interpolLinStrickler)" if interpolate
                   else "those of the zone before")
            self.ledger.approximated("friction zone", "gaps", f"profiles between two friction zones ({len(in_gap)}: "
                                     f"{', '.join(in_gap[:5])}{' ...' if len(in_gap) > 5 else ''}) take the "
                                     f"coefficients of the zone before; Mascaret's are {how}")
        for z in zones:
            if z["k"] not in used_zone:
                self.ledger.approximated("friction zone", f"zone {z['k']}", f"no profile lies in {z['start']:g} .. "
                                         f"{z['end']:g} m of reach {z['reach'].name!r}: the zone has no effect in the "
                                         "case (Mascaret applies it to the calculation points there)")
                continue
            names = [g for g in (f"zone{z['k']}_minor", f"zone{z['k']}_major") if g in groups]
            self.ledger.exact("friction zone", f"zone {z['k']}",
                              f"{law} {z['minor']:g} (minor bed), {z['major']:g} (major bed) from {z['start']:g} to "
                              f"{z['end']:g} m of reach {z['reach'].name!r}: friction group(s) {', '.join(names)}, "
                              "assigned to the profiles in the zone (a link between two zones takes the zone of the "
                              "nearer profile)")
        shared: dict[str, list[str]] = defaultdict(list)  # group -> profiles that combine it with another group
        for p in profiles:
            if len(set(p["friction"])) > 1:
                for gid in set(p["friction"]):
                    shared[gid].append(p["id"])
        for gid, g in groups.items():
            if gid in shared:
                names = shared[gid]
                self.ledger.warn(f"friction group {gid} is not offered as a calibration parameter: profile(s) "
                                 f"{', '.join(names[:4])}{' ...' if len(names) > 4 else ''} combine it with another "
                                 "bed, and the engine fixes the ratio of a profile's section coefficients when it "
                                 "compiles the network (a change of one would scale the whole profile)")
                continue
            name = "K" + re.sub(r"[^A-Za-z0-9_]", "_", gid.replace("zone", "z"))
            lo, hi = _calibration_range(g["type"], g["value"])
            parameters.append({"name": name, "targets": [f"friction:group:{gid}"], "min": lo, "max": hi,
                               "initial": g["value"], "perturbation": round(0.1 * g["value"], 6),
                               "transform": "offset", "unit": unit})
        self.case["friction_groups"] = list(groups.values())
        self.case["profiles"] = profiles
        self.case["parameters"] = parameters
        # conveyance settings
        composition = self.x.integer("parametresModelePhysique/compositionLits", 1)
        self.ledger.approximated("setting", "compositionLits", "minor and major beds convey side by side, each with "
                                 "its own area, perimeter and coefficient, summed ('lumped' per bed); Mascaret's "
                                 + ("Debord model adds the interaction between the beds" if composition == 1 else
                                    "bottom-and-banks model splits the friction differently")
                                 + " (no difference while the water stays in the minor bed)")
        if not self.x.boolean("parametresModelePhysique/conservFrotVertical", False):
            self.ledger.approximated("setting", "conservFrotVertical", "Mascaret ignores the friction of vertical "
                                     "walls (conservFrotVertical = false); a case counts a wetted vertical wall in the "
                                     "perimeter: where the water reaches a wall the conveyance is a little lower")
        planim = self.x.find("parametresPlanimetrageMaillage/planim")
        if planim is not None:
            steps = self.x.numbers("valeursPas", within=planim, default=[])
            self.ledger.approximated("setting", "planimetrage", "rivercal tabulates each surveyed profile itself on "
                                     "2000 depths; Mascaret tabulates it in steps of "
                                     f"{', '.join(f'{s:g}' for s in steps) or '?'} m and interpolates between them "
                                     "(at shallow depths the two differ most)")

    def _profile(self, p: GeoProfile, reach: _Reach, zone: dict, law: str, groups: dict) -> dict | None:
        """A case profile of a surveyed profile (None when refused)."""
        pts = list(p.points)
        # a vertical wall at an end (the survey's closing points, often at 999 m) is the case's own end wall
        while len(pts) > 2 and pts[0].y == pts[1].y and pts[0].z >= pts[1].z:
            pts.pop(0)
        while len(pts) > 2 and pts[-1].y == pts[-2].y and pts[-1].z >= pts[-2].z:
            pts.pop()
        ys = [q.y for q in pts]
        back = next((i for i in range(1, len(ys)) if ys[i] < ys[i - 1]), None)
        if back is not None:
            self.ledger.refused("profile", p.name, f"the positions go back across the valley at y = {ys[back]:g} m "
                                f"(line {pts[back].line} of {self.geo_path.name}): an overhang, which a yz profile "
                                "cannot hold")
            return None
        if ys[-1] - ys[0] <= 0:
            self.ledger.refused("profile", p.name, "the profile has no width")
            return None
        bed = min(q.z for q in pts)
        pid = self.ids.make("profile", p.name)
        reach.profile_ids.append((p, pid))
        out: dict = {"id": pid, "type": "yz", "y": ys, "z": [round(q.z - bed, 6) for q in pts], "conveyance": "lumped"}
        first, last = _minor_bed(pts)
        gid_minor = f"zone{zone['k']}_minor"
        groups.setdefault(gid_minor, {"id": gid_minor, "type": law, "value": zone["minor"]})
        left, right = ys[first] > ys[0], ys[last] < ys[-1]
        if left or right:
            gid_major = f"zone{zone['k']}_major"
            groups.setdefault(gid_major, {"id": gid_major, "type": law, "value": zone["major"]})
            positions = [ys[0]] + ([ys[first]] if left else []) + ([ys[last]] if right else []) + [ys[-1]]
            out["friction_positions"] = positions
            out["friction"] = ([gid_major] if left else []) + [gid_minor] + ([gid_major] if right else [])
        else:
            out["friction"] = [gid_minor]
        note = "" if len(pts) == len(p.points) else " (its closing end walls are the case's own vertical end walls)"
        self.ledger.exact("profile", p.name, f"yz profile {pid!r} at {reach.chainage(p.abscissa):g} m of branch "
                                             f"{reach.branch!r}{note}")
        return out

    def mesh(self) -> None:
        base = "parametresPlanimetrageMaillage"
        method = self.x.integer(f"{base}/methodeMaillage", 1)
        mode = self.x.integer(f"{base}/maillage/modeSaisie", 2)
        all_profiles = [(r, p) for r in self.reaches for p in r.profiles]
        absolute: dict[int, list[float]] = defaultdict(list)  # per reach number: abscissae of points
        if mode == 1:
            self.ledger.approximated("mesh", "maillage", "the grid is read from a file (modeSaisie 1), which is not "
                                     "read: the calculation points are placed at the profiles")
            method = 1
        if method == 1:
            for r, p in all_profiles:
                absolute[r.number].append(p.abscissa)
            how = "at the profiles"
        elif method == 2:
            clav = f"{base}/maillage/maillageClavier"
            n = self.x.integer(f"{clav}/nbZones")
            reaches = self.x.integers(f"{clav}/numBrancheZone", n)
            a = self.x.numbers(f"{clav}/absDebutZone", n)
            b = self.x.numbers(f"{clav}/absFinZone", n)
            counts = self.x.integers(f"{clav}/nbSectionZone", n)
            for k in range(n):
                r = self.reach_of(reaches[k], self.x.find(f"{clav}/numBrancheZone"), f"{clav}/numBrancheZone")
                if not b[k] > a[k] or counts[k] < 0:
                    raise self.x.error(self.x.find(f"{clav}/absFinZone"), f"{clav}/absFinZone",
                                       f"grid zone {k + 1} runs from {a[k]:g} to {b[k]:g} m with {counts[k]} points")
                step = (b[k] - a[k]) / (counts[k] + 1)
                absolute[r.number].extend(a[k] + step * i for i in range(counts[k] + 2))
            how = "by series (zones of equally spaced points)"
        elif method == 3:
            clav = f"{base}/maillage/maillageClavier"
            n = self.x.integer(f"{clav}/nbSections")
            reaches = self.x.integers(f"{clav}/branchesSection", n)
            xs = self.x.numbers(f"{clav}/absSection", n)
            for k in range(n):
                r = self.reach_of(reaches[k], self.x.find(f"{clav}/branchesSection"), f"{clav}/branchesSection")
                absolute[r.number].append(xs[k])
            how = "section by section"
        elif method == 5:
            clav = f"{base}/maillage/maillageClavier"
            n = self.x.integer(f"{clav}/nbPlages")
            first = self.x.integers(f"{clav}/num1erProfPlage", n)
            last = self.x.integers(f"{clav}/numDerProfPlage", n)
            steps = self.x.numbers(f"{clav}/pasEspacePlage", n)
            for k in range(n):
                if not 1 <= first[k] < last[k] <= len(all_profiles) or steps[k] <= 0:
                    raise self.x.error(self.x.find(f"{clav}/num1erProfPlage"), f"{clav}/num1erProfPlage",
                                       f"grid range {k + 1} runs from profile {first[k]} to {last[k]} with a step of "
                                       f"{steps[k]:g} m (the geometry has {len(all_profiles)} profiles)")
                for i in range(first[k] - 1, last[k]):
                    r, p = all_profiles[i]
                    absolute[r.number].append(p.abscissa)
                    if i + 1 < last[k] and all_profiles[i + 1][0] is r:  # Mascaret's MAILLER, method 5
                        distance = all_profiles[i + 1][1].abscissa - p.abscissa
                        pieces = int(abs(distance) / steps[k])
                        if pieces > 1:
                            absolute[r.number].extend(p.abscissa + j * distance / pieces for j in range(1, pieces))
            how = "by ranges of profiles with a maximum step"
        else:
            self.ledger.approximated("mesh", "maillage", f"grid method {method} (the grid of the initial water line) "
                                     "is not read: the calculation points are placed at the profiles")
            for r, p in all_profiles:
                absolute[r.number].append(p.abscissa)
            how = "at the profiles"
        total = 0
        for r in self.reaches:
            chain = sorted({round(r.chainage(a), 6) for a in absolute.get(r.number, [])
                            if r.start - 1e-4 <= a <= r.end + 1e-4} | {0.0, round(r.length, 6)})
            chain = [c for c in chain if 0.0 <= c <= r.length]
            merged = [chain[0]]
            for c in chain[1:]:  # Mascaret merges points closer than 1 mm
                if c - merged[-1] >= 1e-3:
                    merged.append(c)
            merged[-1] = r.length
            r.points = merged
            total += len(merged)
        self.ledger.exact("mesh", "maillage", f"Mascaret's calculation points ({how}), {total} in all, are the "
                          "branches' points")

    def laws_read(self) -> None:
        base = "parametresLoisHydrauliques"
        n = self.x.integer(f"{base}/nb", 0)
        elements = self.x.find(f"{base}/lois")
        items = elements.all("structureParametresLoi") if elements is not None else []
        if len(items) < n:
            raise self.x.error(elements, f"{base}/lois", f"{n} law(s) announced, {len(items)} given")
        for k, e in enumerate(items[:n]):
            name = self.x.text("nom", f"law{k + 1}", within=e)
            law_type = self.x.integer("type", within=e)
            mode = self.x.integer("donnees/modeEntree", 1, within=e)
            entry = {"k": k + 1, "name": name, "type": law_type, "element": e, "law": None, "why": ""}
            if law_type not in LAW_NAMES:
                raise self.x.error(e, f"{base}/lois/structureParametresLoi/type",
                                   f"law {name!r}: type {law_type} is not one of Mascaret's types 1-7")
            if mode != 1:
                entry["why"] = (f"law {name!r} is entered in the case file (modeEntree {mode}), which Mascaret's "
                                "own reader does not take either; save it to a .loi file")
            else:
                file_el = self.x.find("donnees/fichier", e)
                if file_el is None or not file_el.text:
                    raise self.x.error(e, f"{base}/lois/structureParametresLoi/donnees/fichier",
                                       f"law {name!r} names no file")
                entry["law"] = read_law(self.file(file_el.text, file_el, "donnees/fichier"), law_type)
            self.laws.append(entry)

    def law(self, number: int, element: Element | None, path: str) -> dict:
        if not 1 <= number <= len(self.laws):
            raise self.x.error(element, path, f"law number {number} does not exist (the model has {len(self.laws)})")
        return self.laws[number - 1]

    def period_and_engine(self) -> None:
        base = "parametresTemporels"
        dt_m = self.x.number(f"{base}/pasTemps")
        if not dt_m > 0:
            raise self.x.error(self.x.find(f"{base}/pasTemps"), f"{base}/pasTemps", f"time step {dt_m:g} s")
        t0 = self.x.number(f"{base}/tempsInit", 0.0)
        criterion = self.x.integer(f"{base}/critereArret", 1)
        variable = self.x.boolean(f"{base}/pasTempsVar", False)
        courant = self.x.number(f"{base}/nbCourant", 0.8)
        if criterion == 1:
            t_end = self.x.number(f"{base}/tempsMax")
            how = f"to Mascaret's final time {t_end:g} s"
        elif criterion == 2:
            steps = self.x.integer(f"{base}/nbPasTemps")
            t_end = t0 + steps * dt_m
            how = f"{steps} steps of {dt_m:g} s"
        else:
            ends = [float(e["law"]["time"][-1]) for e in self.laws if e["law"] is not None and e["law"].in_time]
            t_end = min(ends) if ends else t0 + 86400.0
            how = "to the end of the shortest law (Mascaret stops when a level is reached at a control point)"
            self.ledger.approximated("setting", "critereArret", "Mascaret stops when the level at its control point "
                                     "reaches coteMax; the case runs to the end of the shortest law")
        if self.o.hours is not None:
            t_end = t0 + self.o.hours * 3600.0
            how = f"{self.o.hours:g} h (--hours)"
        if not t_end > t0:
            raise self.x.error(self.x.find(base), base, f"the computation ends at {t_end:g} s, not after its start "
                                                        f"{t0:g} s")
        stock = self.x.integer("parametresImpressionResultats/pasStockage/pasStock", 1)
        interval = self.o.output_interval or max(stock, 1) * dt_m
        dt = self.o.dt or dt_m
        ms = lambda v: max(round(v * 1000), 1)  # noqa: E731 - whole milliseconds
        interval_ms, dt_ms = ms(interval), ms(dt)
        if interval_ms % dt_ms:
            dt_ms = interval_ms // math.ceil(interval_ms / dt_ms)
        span_ms = ms(t_end - t0)
        if span_ms % interval_ms:
            span_ms = (span_ms // interval_ms + 1) * interval_ms
        self.start = self.origin + pd.Timedelta(milliseconds=round(t0 * 1000))
        self.end = self.start + pd.Timedelta(milliseconds=span_ms)
        self.t0 = t0
        self.case["case"] = {"name": _BAD.sub("_", self.x.path.stem)[:60] or "mascaret",
                             "description": f"imported from the Mascaret model {self.x.path.name}",
                             "start": _iso(self.start), "end": _iso(self.end)}
        engine = {"dt": dt_ms / 1000.0, "output_interval": interval_ms / 1000.0,
                  "cross_sections": self.o.cross_sections}
        h_min = self.x.number("parametresNumeriques/hauteurEauMini", 0.0)
        if 0 < h_min <= 1:
            engine["min_depth"] = h_min
            self.ledger.approximated("setting", "hauteurEauMini", f"Mascaret's minimum depth {h_min:g} m is the "
                                     "engine's min_depth, the upwind depth below which a link carries no flow")
        self.case["engine"] = engine
        step_note = (f"Mascaret adapts its step to a Courant number of {courant:g} (pasTempsVar); the case steps "
                     f"{engine['dt']:g} s (implicit, no Courant limit; the engine divides a step where the flow "
                     "crosses a cell too fast)") if variable else f"time step {engine['dt']:g} s"
        if variable or dt_ms != ms(dt_m):
            self.ledger.approximated("setting", "pasTemps", step_note)
        else:
            self.ledger.exact("setting", "pasTemps", step_note)
        extra = "" if span_ms == ms(t_end - t0) else f", lengthened to {span_ms / 1000:g} s (a whole number of outputs)"
        self.ledger.exact("setting", "period", f"{_iso(self.start)} .. {_iso(self.end)}: {how}{extra}; Mascaret's "
                          f"time 0 is {_iso(self.origin)} (--origin)")
        self.ledger.exact("setting", "pasStock", f"output every {engine['output_interval']:g} s")
        self.cross_section_note()

    def cross_section_note(self) -> None:
        if self.o.cross_sections == "interpolated":
            self.ledger.exact("setting", "cross sections", "each calculation point between two profiles takes the "
                              "profile interpolated between them, as Mascaret interpolates its planimetry")
        else:
            self.ledger.approximated("setting", "cross sections", "each calculation point takes the nearest profile "
                                     "(--cross-sections nearest); Mascaret interpolates between the two profiles "
                                     "around it")

    def _series(self, values: np.ndarray, times: np.ndarray, column: str) -> dict:
        """A law in time as the case's constant ``value`` or a column of ``forcing.csv``."""
        start_s = self.t0
        end_s = self.t0 + (self.end - self.start).total_seconds()
        v = np.asarray(values, dtype=float)
        t = np.asarray(times, dtype=float)
        if np.all(v == v[0]):
            return {"value": float(v[0])}
        keep = (t >= start_s) & (t <= end_s)
        grid = np.unique(np.concatenate([[start_s, end_s], t[keep]]))
        series = pd.Series(np.interp(grid, t, v), index=self.origin + pd.to_timedelta(grid, unit="s"))
        self.series[column] = series
        return {"series": {"file": FORCING_FILE, "column": column}}

    def _covers(self, law: Law, what: str, ident: str, kind: str) -> None:
        t = law["time"]
        end_s = self.t0 + (self.end - self.start).total_seconds()
        if t[0] > self.t0 + 1e-6 or t[-1] < end_s - 1e-6:
            self.ledger.approximated(kind, ident, f"the {what} law {law.path.name} spans {t[0]:g} .. {t[-1]:g} s, "
                                     f"the case {self.t0:g} .. {end_s:g} s: its first and last values are held beyond "
                                     "it")

    def boundaries(self) -> None:
        free = "parametresGeometrieReseau/extrLibres"
        out = []
        ends = {r.node_start: (r, "start") for r in self.reaches}
        ends.update({r.node_end: (r, "end") for r in self.reaches})
        for i, e in enumerate(self.free["ext"]):
            node = self.free_node[i]
            name = self.free["names"][i] if i < len(self.free["names"]) else f"end{e}"
            kind = self.free["type"][i]
            bid = self.ids.make("boundary", name)
            if kind not in BOUNDARY_TYPES:
                raise self.x.error(self.x.find(f"{free}/typeCond"), f"{free}/typeCond",
                                   f"boundary {name!r}: type {kind} is not one of Mascaret's types 1-8")
            what = BOUNDARY_TYPES[kind]
            if node not in ends:
                self.ledger.refused("boundary", name, f"extremity {e} is not the end of any reach")
                continue
            reach, side = ends[node]
            if kind in (1, 2, 3, 4, 8):
                entry = self.law(self.free["law"][i], self.x.find(f"{free}/numLoi"), f"{free}/numLoi")
                law = entry["law"]
                if law is None:
                    self.ledger.refused("boundary", name, entry["why"])
                    continue
            if kind == 1:
                if law.type not in (1, 3):
                    raise self.x.error(self.x.find(f"{free}/numLoi"), f"{free}/numLoi",
                                       f"boundary {name!r} imposes a discharge but its law {entry['name']!r} is a "
                                       f"{LAW_NAMES[law.type]}")
                item = {"id": bid, "node": node, "type": "discharge",
                        **self._series(law["discharge"], law["time"], f"Q_{bid}")}
                self._covers(law, "discharge", name, "boundary")
                self.ledger.exact("boundary", name, f"{what} from law {entry['name']!r} at node {node!r}")
            elif kind == 2:
                if law.type not in (2, 3):
                    raise self.x.error(self.x.find(f"{free}/numLoi"), f"{free}/numLoi",
                                       f"boundary {name!r} imposes a level but its law {entry['name']!r} is a "
                                       f"{LAW_NAMES[law.type]}")
                item = {"id": bid, "node": node, "type": "level",
                        **self._series(law["level"], law["time"], f"h_{bid}")}
                self._covers(law, "level", name, "boundary")
                self.ledger.exact("boundary", name, f"{what} from law {entry['name']!r} at node {node!r}")
            elif kind in (3, 4):
                if law.type not in (4, 5):
                    raise self.x.error(self.x.find(f"{free}/numLoi"), f"{free}/numLoi",
                                       f"boundary {name!r} is a rating but its law {entry['name']!r} is a "
                                       f"{LAW_NAMES[law.type]}")
                levels = [float(v) for v in law["level"]]
                discharges = [float(v) for v in law["discharge"]]
                note = f"{what} from law {entry['name']!r}: a Q(h) rating at node {node!r}"
                if discharges[0] < 0:
                    self.ledger.refused("boundary", name, "the rating starts at a negative discharge")
                    continue
                if discharges[0] > 0:
                    bed = (reach.profiles[0] if side == "start" else reach.profiles[-1]).bed_level
                    if bed < levels[0]:
                        levels.insert(0, bed)
                        discharges.insert(0, 0.0)
                        self.ledger.approximated("boundary", name, f"{note}; the rating starts at "
                                                 f"{law['discharge'][0]:g} m³/s, so a point (bed {bed:g} m, 0 m³/s) "
                                                 "is added below it (a case's rating starts where the outflow stops)")
                    else:
                        self.ledger.refused("boundary", name, "the rating starts above 0 m³/s at or below the bed")
                        continue
                else:
                    self.ledger.exact("boundary", name, note)
                item = {"id": bid, "node": node, "type": "rating",
                        "rating": {"levels": levels, "discharges": discharges}}
            elif kind == 6:
                item = {"id": bid, "node": node, "type": "critical"}
                self.ledger.approximated("boundary", name, "a free outflow, where Mascaret imposes nothing (the flow "
                                         "leaves as it comes): a free outfall at critical depth, which lowers the "
                                         "level just upstream where the flow is subcritical")
            elif kind == 7:
                rating = self._normal_depth(reach, side)
                if rating is None:
                    self.ledger.refused("boundary", name, "normal depth on a reach end without a falling bed")
                    continue
                item = {"id": bid, "node": node, "type": "rating", "rating": rating}
                self.ledger.approximated("boundary", name, "normal depth: a Q(h) rating of uniform flow in the end "
                                         "profile, with its friction and the bed slope between the last two profiles "
                                         f"({rating.pop('_slope'):.4g})")
            elif kind == 8:
                self.ledger.refused("boundary", name, "level and discharge imposed at once: a case imposes one of them")
                continue
            else:
                self.ledger.refused("boundary", name, f"{what}: no counterpart in a case")
                continue
            out.append(item)
        self.case["boundaries"] = out

    def _normal_depth(self, reach: _Reach, side: str) -> dict | None:
        ps = reach.profiles
        a, b = (ps[0], ps[1]) if side == "start" else (ps[-2], ps[-1])
        slope = (a.bed_level - b.bed_level) / (b.abscissa - a.abscissa)
        if slope <= 0:
            return None
        end = ps[0] if side == "start" else ps[-1]
        pid = reach.profile_ids[0 if side == "start" else -1][1] if reach.profile_ids else None
        profile = next((p for p in self.case["profiles"] if p["id"] == pid), None)
        if profile is None:
            return None
        groups = {g["id"]: g for g in self.case["friction_groups"]}
        coefficient = groups[profile["friction"][len(profile["friction"]) // 2]]
        if coefficient["type"] != "strickler":
            return None
        y, z = np.asarray(profile["y"]), np.asarray(profile["z"])
        depths = np.linspace(0.0, max(float(z.max()), 1.0) * 1.5, 41)[1:]
        q = []
        for d in depths:
            area, perimeter = _area_perimeter(y, z, d)
            q.append(coefficient["value"] * area * (area / perimeter) ** (2 / 3) * math.sqrt(slope))
        return {"levels": [end.bed_level] + [end.bed_level + float(d) for d in depths],
                "discharges": [0.0] + [float(v) for v in q], "_slope": slope}

    def laterals(self) -> None:
        base = "parametresApportDeversoirs/debitsApports"
        element = self.x.find(base)
        out = []
        if element is None:
            self.case["laterals"] = out
            return
        n = self.x.integer("nbQApport", 0, within=element)
        names = self.x.strings("noms", within=element)
        reaches = self.x.integers("numBranche", n, within=element)
        where = self.x.numbers("abscisses", n, within=element)
        lengths = self.x.numbers("longueurs", n, within=element, default=[0.0] * n)
        laws = self.x.integers("numLoi", n, within=element)
        for k in range(n):
            name = names[k] if k < len(names) else f"inflow{k + 1}"
            lid = self.ids.make("lateral", name)
            reach = self.reach_of(reaches[k], self.x.find("numBranche", element), f"{base}/numBranche")
            chainage = self.inside(reach, where[k], self.x.find("abscisses", element), f"{base}/abscisses",
                                   f"inflow {name!r}")
            entry = self.law(laws[k], self.x.find("numLoi", element), f"{base}/numLoi")
            law = entry["law"]
            if law is None:
                self.ledger.refused("lateral", name, entry["why"])
                continue
            if law.type != 1:
                raise self.x.error(self.x.find("numLoi", element), f"{base}/numLoi",
                                   f"inflow {name!r}: its law {entry['name']!r} is a {LAW_NAMES[law.type]}, not a "
                                   "hydrograph")
            self._covers(law, "inflow", name, "lateral")
            if lengths[k] < 0:
                raise self.x.error(self.x.find("longueurs", element), f"{base}/longueurs",
                                   f"inflow {name!r} has a negative length {lengths[k]:g} m")
            if lengths[k] == 0:
                out.append({"id": lid, "branch": reach.branch, "chainage": chainage,
                            **self._series(law["discharge"], law["time"], f"L_{lid}")})
                self.ledger.exact("lateral", name, f"point inflow at {chainage:g} m of branch {reach.branch!r} from "
                                                   f"law {entry['name']!r}")
                continue
            # Mascaret's linear inflow: q (m³/s per m) over the stretch, each calculation point taking its share
            end = self.inside(reach, where[k] + lengths[k], self.x.find("longueurs", element), f"{base}/longueurs",
                              f"the end of inflow {name!r}")
            pts = np.asarray(reach.points)
            inside = pts[(pts >= chainage - 1e-9) & (pts <= end + 1e-9)]
            if inside.size == 0:
                inside = np.array([pts[np.argmin(np.abs(pts - chainage))]])
            shares = np.append(np.diff(inside), lengths[k] - (inside[-1] - inside[0]))
            for j, (c, share) in enumerate(zip(inside, shares, strict=True)):
                if share <= 0:
                    continue
                out.append({"id": f"{lid}_{j + 1}"[:64], "branch": reach.branch, "chainage": float(c),
                            **self._series(law["discharge"] * share, law["time"], f"L_{lid}_{j + 1}")})
            self.ledger.approximated("lateral", name, f"an inflow over {lengths[k]:g} m ({chainage:g} .. {end:g} m of "
                                     f"branch {reach.branch!r}; law {entry['name']!r} in m³/s per m): one point inflow "
                                     f"per calculation point of the stretch, each with its share, as Mascaret "
                                     "distributes it")
        self.case["laterals"] = out

    def initial(self) -> None:
        base = "parametresConditionsInitiales"
        self.case["initial"] = {"depth": self.o.initial_depth}
        if self.o.spinup:
            self.case["initial"]["spinup"] = self.o.spinup
        if self.x.boolean(f"{base}/repriseEtude/repriseCalcul", False):
            self.ledger.approximated("initial conditions", "repriseCalcul", "Mascaret restarts from a saved state; the "
                                     f"case cold-starts at a depth of {self.o.initial_depth:g} m")
        if self.x.boolean(f"{base}/ligneEau/LigEauInit", False):
            name = self.x.text(f"{base}/ligneEau/fichLigEau", "")
            present = bool(name) and (self.x.folder / name).is_file()
            self.ledger.approximated("initial conditions", name or "ligneEau", "Mascaret starts from an initial water "
                                     f"line{'' if present else ' (the file is not there)'}; the case cold-starts at a "
                                     f"depth of {self.o.initial_depth:g} m"
                                     + (f" with {self.o.spinup:g} h of spin-up" if self.o.spinup else "")
                                     + ": the first part of the period differs, not the state the forcing leads to")
        else:
            self.ledger.approximated("initial conditions", "ligneEau", "Mascaret starts from a dry or computed state; "
                                     f"the case cold-starts at a depth of {self.o.initial_depth:g} m")

    def stations(self) -> None:
        base = "parametresImpressionResultats/stockage"
        option = self.x.integer(f"{base}/option", 1)
        out: list[dict] = []
        taken: set[tuple[str, float]] = set()

        def add(sid: str, reach: _Reach, chainage: float) -> str:
            key = (reach.branch, round(chainage, 6))
            sid = self.ids.make("station", sid, no_dot=True)
            taken.add(key)
            out.append({"id": sid, "branch": reach.branch, "chainage": chainage, "quantities": ["h", "Q"]})
            return sid

        if option == 2:
            n = self.x.integer(f"{base}/nbSite", 0)
            reaches = self.x.integers(f"{base}/branche", n)
            where = self.x.numbers(f"{base}/abscisse", n)
            for k in range(n):
                reach = self.reach_of(reaches[k], self.x.find(f"{base}/branche"), f"{base}/branche")
                c = self.inside(reach, where[k], self.x.find(f"{base}/abscisse"), f"{base}/abscisse", f"site {k + 1}")
                sid = add(f"site{k + 1}", reach, c)
                self.ledger.exact("station", f"site {k + 1}", f"station {sid!r} (h, Q) at {c:g} m of branch "
                                                               f"{reach.branch!r}")
        else:
            for reach in self.reaches:
                for p, pid in reach.profile_ids:
                    add(pid, reach, reach.chainage(min(max(p.abscissa, reach.start), reach.end)))
            self.ledger.approximated("output", "stockage", "Mascaret stores every calculation point; the case has a "
                                     "station (h, Q) at every profile")
        by_name = {r.name: r for r in self.reaches}
        for spec in self.o.stations:
            reach = by_name.get(spec.reach)
            if reach is None and spec.reach.isdigit() and 1 <= int(spec.reach) <= len(self.reaches):
                reach = self.reaches[int(spec.reach) - 1]
            where = {"file": spec.file, "field": f"line {spec.line}" if spec.line else "stations"}
            if reach is None:
                raise CaseError(f"station {spec.id!r}: no reach {spec.reach!r} (the reaches are "
                                f"{', '.join(repr(r.name) for r in self.reaches)}, or their numbers 1-"
                                f"{len(self.reaches)})", **where)
            tol = 1e-4
            if not reach.start - tol <= spec.abscissa <= reach.end + tol:
                raise CaseError(f"station {spec.id!r} at abscissa {spec.abscissa:g} m lies outside reach "
                                f"{reach.name!r} ({reach.start:g} .. {reach.end:g} m)", **where)
            if any(s["id"] == spec.id for s in out):
                raise CaseError(f"station {spec.id!r} is already a station of the imported model (a profile or an "
                                "output site of that name); choose another id", **where)
            sid = add(spec.id, reach, min(max(reach.chainage(spec.abscissa), 0.0), reach.length))
            self.ledger.exact("station", spec.id, f"station {sid!r} (h, Q) at abscissa {spec.abscissa:g} m of reach "
                                                  f"{reach.name!r} (given with the import)")
        self.case["stations"] = out

    def refusals(self) -> None:
        sing = self.x.find("parametresSingularite")
        n = self.x.integer("parametresSingularite/nbSeuils", 0)
        if n > 0:
            items = sing.descendants("structureParametresSeuil") if sing is not None else []
            for k in range(n):
                e = items[k] if k < len(items) else None
                name = self.x.text("nom", f"weir{k + 1}", within=e) if e is not None else f"weir{k + 1}"
                self.ledger.refused("weir", name, "Mascaret's singularities (weirs, gates, laws across a section) are "
                                    "not converted yet; the case has no structure there")
        n_pc = self.x.integer("parametresSingularite/pertesCharges/nbPerteCharge", 0)
        if n_pc > 0:
            self.ledger.refused("head loss", f"{n_pc} head loss(es)", "singular head losses are not converted")
        n_dev = 0
        devers = self.x.find("parametresApportDeversoirs/devers")
        if devers is not None:
            n_dev = self.x.integer("nbDeversoirs", 0, within=devers)
        if n_dev > 0:
            self.ledger.refused("lateral weir", f"{n_dev} lateral weir(s)", "lateral weirs (flow out over a bank) are "
                                "not converted")
        if self.x.boolean("parametresGeneraux/presenceCasiers", False):
            self.ledger.refused("storage area", "casiers", "storage areas (casiers) and their links are not converted")
        n_store = self.x.integer("parametresCalage/zoneStockage/nbProfils", 0)
        if n_store > 0:
            self.ledger.refused("storage zone", f"{n_store} profile(s)", "storage zones within profiles (water that "
                                "is stored but does not flow) are not converted")
        if self.x.boolean("parametresNumeriques/calcOndeSubmersion", False):
            self.ledger.refused("dam break", "calcOndeSubmersion", "a dam-break wave computation is not converted")
        if self.x.boolean("parametresModelePhysique/debordement/litMajeur", False) or \
                self.x.boolean("parametresModelePhysique/debordement/zoneStock", False):
            self.ledger.approximated("setting", "debordement", "Mascaret's progressive overflow into the major bed: "
                                     "the case fills the major bed as soon as the level reaches it")
        tracers = self.x.find("parametresTraceur")
        if tracers is not None and self.x.boolean("presenceTraceurs", False, within=tracers):
            self.ledger.refused("tracer", "parametresTraceur", "water quality (tracers) is not part of a case",
                                hydraulic=False)
        n_conf = self.x.integer("parametresConfluents/nbConfluents", 0)
        if n_conf > 0:
            self.ledger.approximated("setting", "confluents", f"{n_conf} confluence(s) with their angles and widths: "
                                     "a case's junction is a point where the branches share one level")

    def settings(self) -> None:
        numerics = [("traitImplicitFrot", "implicit friction"), ("implicitNoyauTrans", "implicit transcritical kernel"),
                    ("optimisNoyauTrans", "optimised transcritical kernel"),
                    ("termesNonHydrostatiques", "non-hydrostatic terms"),
                    ("attenuationConvection", "damped convection"),
                    ("perteChargeAutoElargissement", "automatic head loss in expansions")]
        on = [label for tag, label in numerics if self.x.boolean(f"parametresNumeriques/{tag}", False)]
        self.ledger.approximated("setting", "numerics", "Mascaret's numerical options"
                                 + (f" ({', '.join(on)})" if on else "") + " are not carried over: rivercal's engine "
                                 "has its own (implicit friction, momentum-conserving expansions, energy-conserving "
                                 "contractions)")
        if self.x.boolean("parametresModelePhysique/perteChargeConf", False):
            self.ledger.approximated("setting", "perteChargeConf", "head losses at confluences are not modelled")


def _zone_of(abscissa: float, zones: list[dict]) -> dict | None:
    for z in zones:
        if z["start"] - 1e-6 <= abscissa <= z["end"] + 1e-6:
            return z
    return None


def _minor_bed(pts) -> tuple[int, int]:
    marks = [p.bed == "B" for p in pts]
    if not any(marks):
        return 0, len(pts) - 1
    return marks.index(True), len(marks) - 1 - marks[::-1].index(True)


def _calibration_range(law: str, value: float) -> tuple[float, float]:
    """Bounds of a friction group's calibration parameter: a factor 3 either way, inside the plausible range."""
    low, high, _ = FRICTION_RANGES[law]
    return max(low, round(value / 3.0, 6)), min(high, round(value * 3.0, 6))


def _area_perimeter(y: np.ndarray, z: np.ndarray, depth: float) -> tuple[float, float]:
    """Wetted area (m²) and perimeter (m) of a yz profile (heights above its lowest point) at a depth, m."""
    area = perimeter = 0.0
    for y0, z0, y1, z1 in zip(y[:-1], z[:-1], y[1:], z[1:], strict=True):
        lo, hi = min(z0, z1), max(z0, z1)
        if depth <= lo:
            continue
        length = math.hypot(y1 - y0, z1 - z0)
        if depth >= hi:
            area += (y1 - y0) * (depth - 0.5 * (z0 + z1))
            perimeter += length
        else:
            frac = (depth - lo) / (hi - lo)
            area += 0.5 * frac * (y1 - y0) * (depth - lo)
            perimeter += frac * length
    perimeter += max(depth - z[0], 0.0) + max(depth - z[-1], 0.0)
    return area, max(perimeter, 1e-9)


def _iso(t: pd.Timestamp) -> str:
    return t.tz_convert("UTC").strftime("%Y-%m-%dT%H:%M:%S.%f").rstrip("0").rstrip(".") + "Z"


def import_mascaret(xcas: Path | str, out: Path | str, options: ImportOptions | None = None) -> ImportResult:
    """Convert a Mascaret model into a case folder.

    Parameters
    ----------
    xcas
        The model's case file (``.xcas``); the geometry and law files it names are read from its folder.
    out
        The case folder to write (created; the files of an earlier import are replaced).
    options
        :class:`ImportOptions`.

    Returns
    -------
    ImportResult
        The folder, the summary and the ledger.

    Raises
    ------
    CaseError
        When a file cannot be read or holds a bad value (the message names the file, the line and the element or
        column), or when objects that change the hydraulics were refused and partial imports are not allowed (the
        message lists them; ``import.md`` is written all the same).
    """
    options = options or ImportOptions()
    if options.cross_sections not in ("interpolated", "nearest"):
        raise CaseError(f"cross sections {options.cross_sections!r}: choose 'interpolated' or 'nearest'")
    xcas, out = Path(xcas), Path(out)
    converter = _Converter(read_xcas(xcas), options)
    converter.run()
    ledger = converter.ledger
    _branches(converter)
    case = conclude(ledger, out, xcas, allow_partial=options.allow_partial, write=lambda: _write(converter, out))
    net = case.network
    summary = {
        "branches": len(net.branches),
        "points": sum(len(r.points or []) for r in converter.reaches),
        "profiles": len(net.profiles),
        "friction_groups": len(net.friction_groups),
        "boundaries": len(net.boundaries),
        "laterals": len(net.laterals),
        "stations": len(net.stations),
        "start": _iso(case.start),
        "end": _iso(case.end),
        "approximated": ledger.counts("approximated"),
        "refused": ledger.counts("refused"),
    }
    return ImportResult(folder=out, summary=summary, ledger=ledger)


def _branches(c: _Converter) -> None:
    out = []
    for r in c.reaches:
        item = {"id": r.branch, "from_node": r.node_start, "to_node": r.node_end, "length": r.length,
                "cross_sections": r.cross_sections}
        if r.points:
            item["points"] = r.points
        axis = [p.axis for p in r.profiles if p.axis is not None]
        if len(axis) == len(r.profiles) and len(axis) >= 2:
            item["geometry"] = [list(a) for a in axis]
        if not r.cross_sections:
            c.ledger.refused("reach", r.name, "none of its profiles could be converted")
            continue
        out.append(item)
    c.case["branches"] = out


def _write(c: _Converter, out: Path) -> None:
    import tomli_w

    for old in out.glob("*.csv"):
        old.unlink()
    if c.series:
        index = sorted(set().union(*(s.index for s in c.series.values())))
        seconds = (pd.DatetimeIndex(index) - c.origin).total_seconds().to_numpy()
        frame = pd.DataFrame({name: np.interp(seconds, (s.index - c.origin).total_seconds().to_numpy(),
                                              s.to_numpy(dtype=float)) for name, s in c.series.items()},
                             index=pd.DatetimeIndex(index))
        frame.index = frame.index.strftime("%Y-%m-%dT%H:%M:%S.%fZ").str.replace(".000000Z", "Z", regex=False)
        frame.index.name = "time"
        frame.to_csv(out / FORCING_FILE)
    order = ["case", "engine", "initial", "friction_groups", "profiles", "nodes", "branches", "boundaries",
             "laterals", "stations", "parameters"]
    data = {k: c.case[k] for k in order if c.case.get(k) not in (None, [], {})}
    (out / "case.toml").write_text(tomli_w.dumps(_clean(data)), encoding="utf-8")


def _clean(value):
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items() if v is not None and not str(k).startswith("_")}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
