"""D-HYDRO (D-Flow FM 1D) models in and out of cases, read and written with hydrolib-core (layer 6).

- :func:`import_dhydro` converts a D-Flow FM 1D model (an MDU and the files it names) into a case
  folder with ``import.md``, which accounts for every object read: converted exactly, approximated
  (how, and the expected effect) or refused (why).
- :func:`export_dhydro` writes a case as D-Flow FM 1D files.
- :func:`read_exchange` reads the DIMR exchange files of a coupled run (series by D-Flow FM quantity).

The importer sits in :mod:`rivercal.io` (above the case loader): it builds a ``case.toml`` and loads
it with :func:`rivercal.case.load_case`, so an imported case passes the same checks as a written one.
"""

from rivercal.io.dhydro._context import ImportOptions
from rivercal.io.dhydro._export import ExportResult, export_dhydro
from rivercal.io.dhydro._forcing import read_exchange
from rivercal.io.dhydro._import import ImportResult, import_dhydro
from rivercal.io.dhydro._ledger import Entry, Ledger

__all__ = ["Entry", "ExportResult", "ImportOptions", "ImportResult", "Ledger", "export_dhydro", "import_dhydro",
           "read_exchange"]
