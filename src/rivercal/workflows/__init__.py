"""Workflows: what each command of ``rivercal`` does, as library functions that a script can call too.

A workflow takes checked, typed inputs (a model, a :class:`~rivercal.parameters.ParameterSet`, a window
as UTC timestamps …), runs the work, writes its files under an output folder and returns a
JSON-friendly summary. It never prints: it reports what it is doing through a :class:`Progress`
(default: nothing) and logs. The command line (:mod:`rivercal.cli`) parses and checks the options,
calls a workflow and prints the summary.

- :func:`~rivercal.workflows.simulate.simulate_case` — one run, series as CSV and CF NetCDF;
- :func:`~rivercal.workflows.calibrate.calibrate_window` — a calibration over a window, on
  observations or a twin truth;
- :func:`~rivercal.workflows.analyse.analyse_window` — sensitivity, identifiability, residual bias;
- :func:`~rivercal.workflows.online.run_online` — the on-line service over a replay or a watched folder;
- :func:`~rivercal.workflows.twin.run_thesis` — the twin experiments of the reference study and their report.
"""

from rivercal.workflows.progress import NO_PROGRESS, Progress, jsonable

__all__ = ["NO_PROGRESS", "Progress", "jsonable"]
