"""EPA SWMM's command-line runner: ``python -m rivercal.models.swmm.runner INP RPT OUT``.

swmm-toolkit ships the SWMM engine as a library without its ``runswmm`` executable; this runner is that
executable's main in Python: it calls the toolkit's ``swmm_run`` (the function ``runswmm`` calls) on the
three files and exits with status 1 and SWMM's message when the run fails. It serves as the external
program of a black box (``command = ["{python}", "-m", "rivercal.models.swmm.runner", "model.inp",
"model.rpt", "model.out"]``).
"""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    """Run SWMM on INP, writing the report RPT and the binary output OUT; return the exit status."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3:
        sys.stderr.write("usage: python -m rivercal.models.swmm.runner INP RPT OUT\n")
        return 2
    from swmm.toolkit import solver

    try:
        solver.swmm_run(*args)
    except Exception as exc:  # the toolkit raises plain Exceptions that carry SWMM's error text
        sys.stderr.write(f"SWMM failed: {' '.join(str(exc).split())}\n")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
