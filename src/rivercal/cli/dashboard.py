"""``rivercal dashboard``: the read-only web dashboard over a store (:mod:`rivercal.dashboard`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["dashboard"]


def dashboard(
    db: Annotated[Path, typer.Option(help="The SQLite store of the on-line service (read only).")],
    host: Annotated[str, typer.Option(help="Address to listen on (default: this machine only).")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port to listen on.")] = 8050,
) -> None:
    """Serve the live dashboard of a store: estimates, alerts, forecasts, the network map, the cycle log."""
    raise NotImplementedError
