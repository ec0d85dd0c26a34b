"""The dashboard's web application: a read-only Starlette app over one store.

Pages (server-rendered from the Jinja2 templates shared with the reports): ``/`` now (the forecast in
use and why, what changed, the parameters behind it, open alerts), ``/forecast`` (the latest issued
forecast per series with the observations of the 48 h before), ``/estimates``, ``/forecasts`` (forecast
skill by lead time), ``/map``, ``/cycles``; ``/api/version`` tells the page's script when a cycle was
stored (it then fetches the page again and swaps its content, without a reload). Static files: only the
page script and the plotly.js that the ``plotly`` package ships (no CDN, nothing from the internet),
gzip-compressed once in memory and sent compressed to every browser that accepts it (plotly.js: 4.8 MB,
1.5 MB compressed), under an address that carries a hash of the content, so that a browser keeps them
for a year (``cache-control: immutable``) and asks again only when rivercal or plotly is updated; an
``ETag`` answers a revalidation with 304.

Read-only by construction: every request opens the store with :class:`~rivercal.store.Store` in
read-only mode (SQLite ``mode=ro``; in WAL mode a reader sees each committed cycle and never blocks the
writer); only GET and HEAD are answered (405 otherwise); static files come from a fixed list, so
no path reaches the file system; responses carry a Content-Security-Policy that allows scripts from
the dashboard itself only.
"""

from __future__ import annotations

import contextlib
import functools
import gzip
import hashlib
import importlib.resources
import logging
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import HTMLResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Route

from rivercal.dashboard import views
from rivercal.report.pages import environment
from rivercal.store import Store, StoreError

__all__ = ["create_app"]

log = logging.getLogger(__name__)

_SECURITY_HEADERS = {
    "content-security-policy": "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
                               "img-src 'self' data:; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'; "
                               "form-action 'self'",
    "x-content-type-options": "nosniff",
    "referrer-policy": "no-referrer",
    "x-frame-options": "DENY",
}
_PAGES = (("/", "Now"), ("/forecast", "Forecast"), ("/estimates", "Estimates"), ("/forecasts", "Forecast skill"),
          ("/map", "Network map"), ("/cycles", "Cycle log"))
#: How long a browser may keep a static file: a year; its address changes with its content.
_IMMUTABLE = "public, max-age=31536000, immutable"


class Asset:
    """A static file as served: its bytes, a content hash (the ETag and the address' ``v``), and gzipped once.

    Parameters
    ----------
    path
        The file.
    media
        Its media type.
    """

    def __init__(self, path: Path, media: str):
        self.media = media
        self.body = path.read_bytes()
        self.digest = hashlib.sha256(self.body).hexdigest()[:16]

    @functools.cached_property
    def gzipped(self) -> bytes:
        """The body compressed with gzip (level 6: plotly.js 4.8 MB → 1.4 MB in about a second), once."""
        return gzip.compress(self.body, compresslevel=6, mtime=0)


def _static_files() -> dict[str, tuple[Path, str]]:
    """The only files the dashboard serves: name -> (path, media type)."""
    plotly = importlib.resources.files("plotly") / "package_data" / "plotly.min.js"
    script = importlib.resources.files("rivercal.dashboard") / "static" / "dashboard.js"
    return {"plotly.min.js": (Path(str(plotly)), "text/javascript; charset=utf-8"),
            "dashboard.js": (Path(str(script)), "text/javascript; charset=utf-8")}


def _accepts_gzip(request: Request) -> bool:
    """Whether the request's Accept-Encoding allows gzip (a q=0 refuses it)."""
    for part in request.headers.get("accept-encoding", "").split(","):
        name, _, params = part.strip().partition(";")
        if name.strip().lower() in ("gzip", "*"):
            q = params.strip().removeprefix("q=") if params.strip().startswith("q=") else "1"
            try:
                return float(q) > 0
            except ValueError:
                return False
    return False


#: Largest request body the dashboard reads (and drops) before it answers, bytes: it takes none.
MAX_BODY = 64 * 1024


class _ReadOnly:
    """ASGI middleware: GET and HEAD only, and the security headers on every response.

    A request that carries a body is read to its end (and the body dropped) before it is answered: the
    dashboard takes none, but a body the server cannot parse (a broken chunked encoding) makes the server
    answer 400 and close the connection itself while the request is being handled, and an answer sent
    after that ended in a logged traceback. Such a request is now left to the server's answer; a body
    larger than :data:`MAX_BODY` gets 413.
    """

    def __init__(self, app: Any):
        self.app = app

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if _has_body(scope):
            read = await _drop_body(receive)
            if read is None:  # the client went away, or the server refused the body and answered already
                return
            if read > MAX_BODY:
                response = PlainTextResponse(f"the dashboard takes no request body (got more than {MAX_BODY} bytes)",
                                             status_code=413, headers={"connection": "close", **_SECURITY_HEADERS})
                await response(scope, receive, send)
                return
            receive = _empty_body(receive)
        if scope["method"] not in ("GET", "HEAD"):
            response = PlainTextResponse("the dashboard is read-only: only GET and HEAD are allowed", status_code=405,
                                         headers={"allow": "GET, HEAD", **_SECURITY_HEADERS})
            await response(scope, receive, send)
            return

        async def with_headers(message: dict) -> None:
            if message["type"] == "http.response.start":
                headers = [(k, v) for k, v in message.get("headers", []) if k.decode().lower() not in
                           _SECURITY_HEADERS]
                headers += [(k.encode(), v.encode()) for k, v in _SECURITY_HEADERS.items()]
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, with_headers)


def _has_body(scope: dict) -> bool:
    """Whether a request announces a body (chunked, or a positive or unreadable Content-Length)."""
    for key, value in scope.get("headers", []):
        name = key.decode("latin-1").lower()
        if name == "transfer-encoding":
            return True
        if name == "content-length" and value.strip() not in (b"0", b""):
            return True
    return False


async def _drop_body(receive: Any) -> int | None:
    """Read a request's body to its end, keeping none of it: the bytes read (up to just over MAX_BODY), or None.

    None when the connection ended first (the client left, or the server refused a malformed body).
    """
    read = 0
    while True:
        message = await receive()
        if message["type"] == "http.disconnect":
            return None
        read += len(message.get("body", b""))
        if read > MAX_BODY or not message.get("more_body", False):
            return read


def _empty_body(receive: Any) -> Any:
    """A ``receive`` whose first message is the (already read) end of the body; later ones are the server's."""
    sent = False

    async def replay() -> dict:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": b"", "more_body": False}
        return await receive()

    return replay


class _Problem(Exception):
    """A request the dashboard cannot answer (unknown run, bad parameter): status and text for the page."""

    def __init__(self, status: int, text: str):
        super().__init__(text)
        self.status = status
        self.text = text


def create_app(db: str | Path, *, poll_s: float = 2.0) -> Starlette:
    """The dashboard of the store ``db`` (opened read-only on every request).

    Parameters
    ----------
    db
        The SQLite store.
    poll_s
        How often an open page asks whether a new cycle was stored, s.
    """
    db = Path(db)
    env = environment("rivercal.dashboard")
    files = _static_files()
    assets: dict[str, Asset] = {}

    def asset_of(name: str) -> Asset:
        """The static file ``name``, read and compressed at its first request (then kept)."""
        if name not in assets:
            path, media = files[name]
            assets[name] = Asset(path, media)
        return assets[name]

    def static_url(name: str) -> str:
        return f"/static/{name}?v={asset_of(name).digest}"


    @contextlib.contextmanager
    def opened(request: Request) -> Iterator[tuple[Store, Any, list[str]]]:
        try:
            store = Store(db, readonly=True)
        except StoreError as exc:
            raise _Problem(503, f"the store cannot be read: {exc}") from None
        try:
            runs = store.runs()
            names = [str(n) for n in runs.sort_values("created")["name"]]
            if not names:
                raise _Problem(404, f"the store {db} holds no run yet")
            name = request.query_params.get("run") or names[-1]
            run = store.get_run(name)
            if run is None:
                raise _Problem(404, f"no run named {name!r} in the store (it has {', '.join(names)})")
            yield store, run, names
        finally:
            store.close()

    def page(request: Request, template: str, **context: Any) -> Response:
        try:
            with opened(request) as (store, run, names):
                data = context.pop("view")(store, run, request)
                html = env.get_template(template).render(
                    title=f"rivercal — {run.name}", run=run.name, runs=names, case=run.case, pages=_PAGES,
                    path=request.url.path, version=views.run_version(store, run), poll_ms=int(poll_s * 1000),
                    stamp="live", static_url=static_url, **data, **context)
        except _Problem as exc:
            html = env.get_template("problem.html").render(title="rivercal dashboard", text=exc.text, pages=_PAGES,
                                                           path=request.url.path, stamp="live")
            return HTMLResponse(html, status_code=exc.status)
        return HTMLResponse(html)

    async def now(request: Request) -> Response:
        return page(request, "now.html", view=lambda s, r, q: views.now_view(s, r))

    async def forecast(request: Request) -> Response:
        return page(request, "forecast.html", view=lambda s, r, q: views.forecast_view(s, r))

    async def estimates(request: Request) -> Response:
        return page(request, "estimates.html", view=lambda s, r, q: views.estimates_view(s, r))

    def forecast_data(store: Store, run: Any, request: Request) -> dict[str, Any]:
        series_list, leads = views.forecast_choices(store, run)
        if not series_list:
            return {"series_list": [], "leads": [], "view": None}
        series = request.query_params.get("series") or series_list[0]
        if series not in series_list:
            raise _Problem(404, f"no forecast series {series!r} in run {run.name} (it has {', '.join(series_list)})")
        text = request.query_params.get("lead") or ("24" if 24.0 in leads else f"{leads[-1]:g}")
        try:
            lead = float(text)
        except ValueError:
            lead = math.nan
        if not any(math.isclose(lead, v) for v in leads):
            stored = ", ".join(f"{v:g}" for v in leads)
            raise _Problem(400, f"lead {text!r}: choose one of the stored lead times {stored} h")
        return {"series_list": series_list, "leads": leads, "view": views.forecasts_view(store, run, series, lead)}

    async def forecasts(request: Request) -> Response:
        return page(request, "forecasts.html", view=forecast_data)

    async def network_map(request: Request) -> Response:
        return page(request, "map.html", view=lambda s, r, q: views.map_view(s, r))

    async def cycles(request: Request) -> Response:
        return page(request, "cycles.html", view=lambda s, r, q: views.cycles_view(s, r))

    async def version(request: Request) -> Response:
        try:
            with opened(request) as (store, run, _):
                return JSONResponse({"run": run.name, "version": views.run_version(store, run)},
                                    headers={"cache-control": "no-store"})
        except _Problem as exc:
            return JSONResponse({"error": exc.text}, status_code=exc.status)

    async def asset(request: Request) -> Response:
        name = request.path_params["name"]
        if name not in files:
            return PlainTextResponse("not found", status_code=404)
        item = asset_of(name)
        current = request.query_params.get("v") == item.digest
        headers = {"cache-control": _IMMUTABLE if current else "no-cache", "etag": f'"{item.digest}"',
                   "vary": "accept-encoding"}
        if request.headers.get("if-none-match", "").strip() in (f'"{item.digest}"', f'W/"{item.digest}"'):
            return Response(status_code=304, headers=headers)
        if _accepts_gzip(request):
            body = await run_in_threadpool(lambda: item.gzipped)  # the first time: compress off the event loop
            return Response(body, media_type=item.media, headers={**headers, "content-encoding": "gzip"})
        return Response(item.body, media_type=item.media, headers=headers)

    routes = [Route("/", now), Route("/forecast", forecast), Route("/estimates", estimates),
              Route("/forecasts", forecasts), Route("/map", network_map), Route("/cycles", cycles),
              Route("/api/version", version), Route("/static/{name}", asset)]
    return Starlette(routes=routes, middleware=[Middleware(_ReadOnly)])
