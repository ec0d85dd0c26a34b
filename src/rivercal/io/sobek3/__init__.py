"""SOBEK 3 models into cases (layer 4): ``Flow1D.md1d`` and the files it names, with an account of every object.

- :func:`import_sobek3` converts a SOBEK 3 1D model (the md1d, ``NetworkDefinition.ini``, the cross-section
  locations and definitions, the roughness files, boundaries and laterals with their ``.bc`` file, structures,
  observation points, initial fields, retention areas) into a case folder with ``import.md``, which accounts for
  every object read: converted exactly, approximated (how, and the expected effect) or refused (why).
- :func:`read_results` reads the SOBEK 3 kernel's own results (``gridpoints.nc``, ``observations.nc``).

The files are read by a small INI reader of its own (:mod:`rivercal.io.sobek3._ini`) that keeps every value's
file and line, so that a bad value is reported with its file, line and key. The case is written as
``case.toml`` and loaded with :func:`rivercal.case.load_case`, so an imported case passes the same checks as a
written one.
"""

from rivercal.io.sobek3._context import ImportOptions, Sobek3Ledger
from rivercal.io.sobek3._import import ImportResult, import_sobek3
from rivercal.io.sobek3._results import Sobek3Results, read_results

__all__ = ["ImportOptions", "ImportResult", "Sobek3Ledger", "Sobek3Results", "import_sobek3", "read_results"]
