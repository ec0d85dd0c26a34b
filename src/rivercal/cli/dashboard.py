"""``rivercal dashboard``: the read-only web dashboard over a store (:mod:`rivercal.dashboard`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rivercal.cli.common import err_console
from rivercal.cli.options import check_number
from rivercal.errors import OptionError

__all__ = ["dashboard"]


def dashboard(
    db: Annotated[Path, typer.Option(help="The SQLite store of the on-line service (opened read-only).")],
    host: Annotated[str, typer.Option(help="Address to listen on (default: this machine only).")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port to listen on.")] = 8050,
    poll: Annotated[float, typer.Option(help="Seconds between an open page's looks for a new cycle.")] = 2.0,
) -> None:
    """Serve the live dashboard of a store: estimates, alerts, forecasts, the network map, the cycle log."""
    try:
        from rivercal.dashboard import serve
        from rivercal.dashboard.app import create_app  # noqa: F401 - fails here when the extra is missing
    except ImportError as exc:
        raise OptionError(f"the dashboard needs the 'dashboard' extra (pip install 'rivercal[dashboard]'): {exc}",
                          option="dashboard") from None
    from rivercal.store import Store, StoreError

    if not db.is_file():
        raise OptionError(f"--db {db}: no such store", option="--db")
    try:
        Store(db, readonly=True).close()
    except StoreError as exc:
        raise OptionError(f"--db {db}: {exc}", option="--db") from None
    check_number(port, "--port", low=0, high=65535)
    check_number(poll, "--poll", low=0, low_open=True)
    err_console.print(f"rivercal dashboard of {db} on http://{host}:{port}/ (read only; Ctrl-C stops it)",
                      highlight=False)
    serve(db, host=host, port=port, poll_s=poll)
