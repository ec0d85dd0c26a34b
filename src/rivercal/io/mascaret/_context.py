"""What the steps of a Mascaret import share: Mascaret's codes, the reaches as read and the case ids they get.

Also the converter's state (the model read, the options, the ledger, the case being built) and the helpers every
step uses: :class:`_Context`, which the geometry steps (``_geometry``) and the forcing steps (``_forcing``) extend.
"""

from __future__ import annotations

import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from rivercal.io.mascaret._files import GeoProfile
from rivercal.io.mascaret._ledger import Ledger
from rivercal.io.mascaret._xcas import Element, Xcas

if TYPE_CHECKING:
    from rivercal.io.mascaret._import import ImportOptions

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


class _Context:
    """The state of one import and the helpers every step uses (the steps are in ``_Converter.run``)."""

    # set by the steps: kernel (code), geometry (geo_path), network (free, free_node), period_and_engine (the rest)
    code: int
    geo_path: Path
    free: dict
    free_node: dict[int, str]
    start: pd.Timestamp
    end: pd.Timestamp
    t0: float

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


def _iso(t: pd.Timestamp) -> str:
    return t.tz_convert("UTC").strftime("%Y-%m-%dT%H:%M:%S.%f").rstrip("0").rstrip(".") + "Z"
