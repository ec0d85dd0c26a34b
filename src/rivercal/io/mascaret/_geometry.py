"""The geometry steps of a Mascaret import: reaches and nodes, profiles and friction zones, grid, stations."""

from __future__ import annotations

import re
from collections import defaultdict

from rivercal.errors import CaseError
from rivercal.io.mascaret._context import FRICTION_LAWS, _Context, _Reach
from rivercal.io.mascaret._files import Geometry, GeoProfile, read_geometry
from rivercal.network import FRICTION_RANGES


class _GeometrySteps(_Context):
    """The steps that build the network: branches, nodes, profiles, friction groups, points and stations."""

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
        for p in parameters:  # import.md lists them, as the D-HYDRO and SOBEK 3 imports do
            self.ledger.parameters.append(f"`{p['name']}`: {p['targets'][0]}, {p['min']:g} .. {p['max']:g} "
                                          f"{p['unit']}, initial {p['initial']:g}")
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
