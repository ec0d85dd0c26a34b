"""The read-only web dashboard over a store (layer 7½).

:func:`~rivercal.dashboard.app.create_app` builds the Starlette application; :func:`serve` runs it with
uvicorn (``rivercal dashboard --db run.sqlite``). Needs the ``dashboard`` extra (starlette, uvicorn,
plotly for its bundled plotly.js): ``pip install rivercal[dashboard]``.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["serve"]


def serve(db: str | Path, *, host: str = "127.0.0.1", port: int = 8050, poll_s: float = 2.0) -> None:
    """Serve the dashboard of the store ``db`` until interrupted (bound to ``host``: this machine by default)."""
    import uvicorn

    from rivercal.dashboard.app import create_app

    uvicorn.run(create_app(db, poll_s=poll_s), host=host, port=port, log_level="warning", access_log=False)
