"""The command line run in the test's own process, as the console script runs it.

Typer's test runner calls the real app (the same options, commands, error guard and exit statuses) with
its own stdout and stderr. The root logger is set aside while it runs, so that the command's own logging
set-up writes its records to that stderr as in a fresh process. What only a separate process can show —
the ``python -m rivercal.cli`` entry point, compiled kernels loaded by the next process, signals, a
server — is tested with ``subprocess`` in the modules that need it.

In-process runs save each command the start of a Python process with rivercal's numerical stack
(imports and numba's set-up, about 2–3 s per command on this suite's machine).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from typer.testing import CliRunner

from rivercal.cli.main import app


@dataclass(frozen=True)
class Completed:
    """What a finished command left, named as :class:`subprocess.CompletedProcess` names it."""

    args: tuple[str, ...]
    returncode: int
    stdout: str
    stderr: str


def rivercal(*args: str, env: dict[str, str] | None = None) -> Completed:
    """Run ``rivercal ARGS`` in this process; ``env`` adds or replaces environment variables while it runs."""
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    root.handlers.clear()  # the command's logging.basicConfig then installs its own handler, as in a new process
    try:
        result = CliRunner().invoke(app, list(args), env=env, catch_exceptions=False)
    finally:
        for handler in root.handlers:
            handler.close()
        root.handlers[:] = handlers
        root.setLevel(level)
    return Completed(tuple(args), result.exit_code, result.stdout, result.stderr)
