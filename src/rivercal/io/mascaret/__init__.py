"""Mascaret models (TELEMAC-Mascaret's 1D engine) into cases (layer 4).

- :func:`import_mascaret` converts a Mascaret model (its ``.xcas`` case file and the ``.geo`` geometry and
  ``.loi`` laws it names) into a case folder with ``import.md``, which accounts for every object read:
  converted exactly, approximated (how, and the expected effect) or refused (why).
- :func:`read_geometry`, :func:`read_law` and :func:`read_xcas` read the files themselves; every bad value is a
  :class:`~rivercal.errors.CaseError` naming the file, the line and the key.

The importer builds a ``case.toml`` and loads it with :func:`rivercal.case.load_case`, so an imported case
passes the same checks as a written one. Writing the case needs tomli-w (``pip install 'rivercal[mascaret]'``).
"""

from rivercal.io.mascaret._files import Geometry, GeoPoint, GeoProfile, Law, read_geometry, read_law, read_station_list
from rivercal.io.mascaret._import import ImportOptions, ImportResult, StationSpec, import_mascaret
from rivercal.io.mascaret._ledger import Entry, Ledger
from rivercal.io.mascaret._xcas import Xcas, read_xcas

__all__ = ["Entry", "GeoPoint", "GeoProfile", "Geometry", "ImportOptions", "ImportResult", "Law", "Ledger",
           "StationSpec", "Xcas", "import_mascaret", "read_geometry", "read_law", "read_station_list", "read_xcas"]
