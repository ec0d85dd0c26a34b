"""The forcing steps of a Mascaret import: its laws, the period and time step, boundaries, laterals, initial state."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from rivercal.io.mascaret._context import _BAD, BOUNDARY_TYPES, FORCING_FILE, _Context, _iso, _Reach
from rivercal.io.mascaret._files import LAW_NAMES, Law, read_law
from rivercal.io.mascaret._xcas import Element


class _ForcingSteps(_Context):
    """The steps that drive the network: laws, period and engine settings, boundaries, laterals, initial state."""

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
        if self.o.cross_sections == "points":
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
            if kind in (1, 2):  # an imposed discharge or level: its law's type, column and series name
                quantity, types, prefix = ("discharge", (1, 3), "Q") if kind == 1 else ("level", (2, 3), "h")
                if law.type not in types:
                    raise self.x.error(self.x.find(f"{free}/numLoi"), f"{free}/numLoi",
                                       f"boundary {name!r} imposes a {quantity} but its law {entry['name']!r} is a "
                                       f"{LAW_NAMES[law.type]}")
                item = {"id": bid, "node": node, "type": quantity,
                        **self._series(law[quantity], law["time"], f"{prefix}_{bid}")}
                self._covers(law, quantity, name, "boundary")
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
