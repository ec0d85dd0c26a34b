"""``rivercal dashboard``: the read-only web dashboard over a store (:mod:`rivercal.dashboard`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rivercal.cli.common import err_console
from rivercal.cli.options import check_number
from rivercal.errors import OptionError, RivercalError

__all__ = ["dashboard"]


def dashboard(
    db: Annotated[Path, typer.Option(help="The SQLite store of the on-line service (opened read-only).")],
    host: Annotated[str, typer.Option(help="Address to listen on (default: this machine only).")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port to listen on.")] = 8050,
    poll: Annotated[float, typer.Option(help="Seconds between an open page's looks for a new cycle.")] = 2.0,
    case: Annotated[list[str] | None, typer.Option(
        help="A run's model: a case folder or model.toml, for the map, the parameters in words and the DSS's values "
             "(the store knows an imported model by its name, not by its folder); repeatable.")] = None,
) -> None:
    """Serve the live dashboard of a store: the forecast in use and why, the latest forecast per station, more.

    Also the estimates against the DSS, the alerts, the forecast skill, the network map of the level error and
    the cycle log.
    """
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
    if case:
        from rivercal.dashboard.facts import register_model

        with Store(db, readonly=True) as store:
            served = sorted(set(store.runs()["case"]))
        for source in case:
            name = register_model(source)
            if name not in served:
                raise OptionError(f"--case {source}: that is the model {name!r}; the runs of {db} serve "
                                  f"{', '.join(map(repr, served)) or 'none'}", option="--case")
    check_number(port, "--port", low=0, high=65535)
    check_number(poll, "--poll", low=0, low_open=True)
    _check_address(host, port)
    err_console.print(f"rivercal dashboard of {db} on http://{host}:{port}/ (read only; Ctrl-C stops it)",
                      highlight=False)
    try:
        serve(db, host=host, port=port, poll_s=poll)
    except SystemExit as exc:  # uvicorn's "startup failed" (3) is not rivercal's "model run failed"
        if exc.code in (None, 0):
            raise
        raise RivercalError(f"the dashboard could not start serving on {host}:{port} (the server said why above)") \
            from None


def _check_address(host: str, port: int) -> None:
    """``--host``/``--port``: an address of this machine, a port free to listen on (checked by binding to it)."""
    import errno
    import socket

    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except (socket.gaierror, UnicodeError) as exc:
        raise OptionError(f"--host {host}: not an address (nor a name this machine can look up: "
                          f"{getattr(exc, 'strerror', None) or exc}); e.g. 127.0.0.1 (this machine only) or 0.0.0.0 "
                          "(every network)", option="--host") from None
    with socket.socket(family, kind, proto) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(address)
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise OptionError(f"--port {port}: already in use on {host}; give another port", option="--port") \
                    from None
            if exc.errno in (errno.EACCES, errno.EPERM):
                raise OptionError(f"--port {port}: not allowed for this user ({exc.strerror}); ports below 1024 need "
                                  "privileges, e.g. 8050", option="--port") from None
            raise OptionError(f"--host {host}: cannot listen there ({exc.strerror or exc}); is it an address of "
                              "this machine? e.g. 127.0.0.1 or 0.0.0.0", option="--host") from None
