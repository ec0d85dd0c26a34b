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

Here: the options, the order of the steps, the model-wide settings and refusals, and the writing of the case. The
geometry steps are in ``_geometry``, the forcing steps in ``_forcing``, and what they share in ``_context``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError
from rivercal.io.ledger import conclude
from rivercal.io.mascaret._context import FORCING_FILE, KERNELS, _iso
from rivercal.io.mascaret._forcing import _ForcingSteps
from rivercal.io.mascaret._geometry import _GeometrySteps
from rivercal.io.mascaret._ledger import Ledger
from rivercal.io.mascaret._xcas import read_xcas

__all__ = ["ImportOptions", "ImportResult", "StationSpec", "import_mascaret"]



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
        ``points`` (Mascaret's way: each calculation point takes the profile interpolated at it between the two
        around it; the case's ``engine.cross_sections``) or ``nearest``.
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
    cross_sections: str = "points"
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
        refused; the case period; the names of the calibration parameters written.
    ledger
        The full account (also in ``import.md``).
    """

    folder: Path
    summary: dict
    ledger: Ledger


class _Converter(_GeometrySteps, _ForcingSteps):
    """One import: the steps in their order, and the model-wide settings and refusals."""

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
    if options.cross_sections not in ("points", "nearest"):
        raise CaseError(f"cross sections {options.cross_sections!r}: choose 'points' or 'nearest'")
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
        "parameters": [p.name for p in case.spec.parameters],
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
