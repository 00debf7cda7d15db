"""The web application of ``dsim serve``: FastAPI over the model database
(:mod:`dsim.serve.store`), pages rendered with Jinja2 and made live with htmx,
its server-sent-events extension and uPlot (all vendored in ``static/``).

:func:`create_app` makes the application; the routes are in
:mod:`dsim.serve.routes`.  The guard in front of them (:class:`Guard`) keeps
the server safe by default: only the host names it is bound to (no DNS
rebinding), a token when it is reachable from elsewhere, no request that another
web site's page makes on the user's behalf, and a limit on the size of what is
sent.
"""
from __future__ import annotations

import hmac
import sys
import traceback
from contextlib import asynccontextmanager
from pathlib import Path
from urllib.parse import urlencode, urlsplit

from fastapi import FastAPI, HTTPException, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, PlainTextResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates
from starlette.exceptions import HTTPException as StarletteHTTPException

from dsim.serve.jobs import Jobs
from dsim.serve.owner import lock_database, server_identity
from dsim.serve.store import Store
from dsim.serve import routes

HERE = Path(__file__).parent
COOKIE = "dsim_token"
#: largest request body (an upload), bytes
MAX_UPLOAD = 512 << 20


def _respond(scope, receive, send, response):
    return response(scope, receive, send)


#: the names of this machine's loopback interface, as a Host header spells them
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")


def accepted_hosts(host: str, port: int) -> tuple[str, ...] | None:
    """The Host headers a server bound to ``host``:``port`` answers: the loopback
    names and the bound address, each with the port; None for a wildcard address
    (0.0.0.0, ::), whose names are not known: such a server always has a token."""
    if host in ("0.0.0.0", "::", ""):
        return None
    shown = f"[{host}]" if ":" in host else host
    return tuple(dict.fromkeys(f"{name}:{port}" for name in (*LOOPBACK_NAMES, shown)))


class Guard:
    """ASGI middleware: the Host header is one of ``hosts`` (a web page on a name that
    was made to resolve to 127.0.0.1, DNS rebinding, is refused before anything
    else), the token (header ``Authorization: Bearer``, the cookie it sets, or
    ``?token=`` once, which sets the cookie), same-origin requests only for anything
    that changes something, and at most ``max_body`` bytes sent.

    ``hosts``: the accepted Host headers (``name:port``; a bare name accepts any
    port, as FastAPI's TestClient sends one); None accepts any Host, which only a
    server with a token may do (:func:`accepted_hosts`)."""

    def __init__(self, app, token: str | None, max_body: int,
                 hosts: tuple[str, ...] | None = LOOPBACK_NAMES):
        if hosts is None and not token:
            raise ValueError("a server that accepts any Host header needs a token")
        self.app, self.token, self.max_body = app, token, max_body
        self.hosts = None if hosts is None else tuple(h.lower() for h in hosts)

    def _host_ok(self, host: str) -> bool:
        if self.hosts is None:
            return True
        host = host.lower()
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        return host in self.hosts or name in self.hosts

    def _same_origin(self, origin: str, host: str) -> bool:
        """Whether a request's Origin is this server's own pages: an accepted host
        (not merely the Host header, which a rebinding page controls too)."""
        parts = urlsplit(origin)
        return (parts.scheme in ("http", "https") and parts.netloc.lower() == host.lower()
                and self._host_ok(parts.netloc))

    def _authorized(self, request: Request) -> bool:
        if not self.token:
            return True
        header = request.headers.get("authorization", "")
        supplied = [header[7:].strip() if header.lower().startswith("bearer ") else "",
                    request.cookies.get(COOKIE, ""), request.query_params.get("token", "")]
        return any(s and hmac.compare_digest(s.encode(), self.token.encode())
                   for s in supplied)

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        request = Request(scope)
        host = request.headers.get("host", "")
        if not self._host_ok(host):
            # the one thing a rebinding page cannot choose is the name in its address
            # bar, which the browser sends as Host: refuse it before anything runs
            shown = "".join(c for c in host if c.isprintable())[:100]
            return await _respond(scope, receive, send, PlainTextResponse(
                f"421: this dsim server answers only to {', '.join(self.hosts)} "
                f"(the request was for '{shown}')", status_code=421))
        if not self._authorized(request):
            return await _respond(scope, receive, send, HTMLResponse(
                "<h1>401: this dsim server needs its token</h1><p>Open the address that "
                "<code>dsim serve</code> printed (it ends in <code>?token=...</code>).</p>",
                status_code=401))
        if self.token and "token" in request.query_params:
            # the token leaves the address bar: a cookie carries it from now on
            rest = [(k, v) for k, v in request.query_params.multi_items() if k != "token"]
            response = RedirectResponse(request.url.path + ("?" + urlencode(rest) if rest
                                                            else ""), status_code=303)
            response.set_cookie(COOKIE, self.token, httponly=True, samesite="strict")
            return await _respond(scope, receive, send, response)
        if request.method not in ("GET", "HEAD", "OPTIONS"):
            origin = request.headers.get("origin")
            if origin is not None and not self._same_origin(origin, host):
                return await _respond(scope, receive, send, HTMLResponse(
                    "403: a request from another site", status_code=403))
            length = request.headers.get("content-length", "")
            if length.isdigit() and int(length) > self.max_body:
                return await _respond(scope, receive, send, _too_large(self.max_body))
        return await self.app(scope, self._counting(receive), send)

    def _counting(self, receive):
        received = 0

        async def counted():
            nonlocal received
            message = await receive()
            received += len(message.get("body", b""))
            if received > self.max_body:
                raise HTTPException(413, f"the upload is larger than "
                                         f"{self.max_body / 2**20:.0f} MiB")
            return message
        return counted


def _too_large(limit: int) -> HTMLResponse:
    return HTMLResponse(f"413: the upload is larger than {limit / 2**20:.0f} MiB",
                        status_code=413)


def _wants_json(request: Request) -> bool:
    return request.url.path.startswith("/api/")


def create_app(db_path, token: str | None = None, slots: int = 2,
               max_upload: int = MAX_UPLOAD,
               hosts: tuple[str, ...] | None = LOOPBACK_NAMES) -> FastAPI:
    """The application over the database at ``db_path`` (created on first use);
    ``slots``: runs at once; ``max_upload``: largest upload in bytes; ``hosts``: the
    Host headers it answers (:class:`Guard`, :func:`accepted_hosts`)."""
    if hosts is None and not token:  # any Host and no token: open to DNS rebinding
        raise ValueError("a server that accepts any Host header needs a token")
    # before the database is touched: one server per database (InputError naming
    # the other server's pid), held until the application shuts down
    lock = lock_database(db_path)
    store = Store(db_path, owner=server_identity())

    @asynccontextmanager
    async def lifespan(app):
        try:
            store.remove_incoming()
            jobs.start()
            yield
            jobs.shutdown()
        finally:
            lock.release()

    jobs = Jobs(store, slots)
    app = FastAPI(title="dsim serve", lifespan=lifespan, docs_url="/api/docs",
                  redoc_url=None, openapi_url="/api/openapi.json")
    app.state.store = store
    app.state.jobs = jobs
    app.state.max_upload = max_upload
    app.state.templates = Jinja2Templates(directory=str(HERE / "templates"))
    routes.add_filters(app.state.templates.env)
    app.mount("/static", StaticFiles(directory=str(HERE / "static")), name="static")
    app.include_router(routes.router)
    app.include_router(routes.api)

    # Starlette's own (a malformed multipart body, 400) as well as FastAPI's
    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, error: StarletteHTTPException):
        if _wants_json(request):
            return JSONResponse({"problems": [str(error.detail)]}, status_code=error.status_code)
        return app.state.templates.TemplateResponse(
            request, "error.html", {"status": error.status_code,
                                    "problems": [str(error.detail)]},
            status_code=error.status_code)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, error: RequestValidationError):
        # FastAPI's list of dicts becomes one line per problem, as everywhere else
        problems = [f"{'.'.join(str(p) for p in e.get('loc', ()))}: {e.get('msg', '')}"
                    for e in error.errors()]
        return await http_error(request, HTTPException(422, "; ".join(problems)[:500]))

    @app.exception_handler(Exception)
    async def unexpected(request: Request, error: Exception):
        # the user gets one line; the traceback goes to the server's log
        traceback.print_exception(error, file=sys.stderr)
        line = f"internal error: {type(error).__name__}: {error}"
        if _wants_json(request):
            return JSONResponse({"problems": [line]}, status_code=500)
        return HTMLResponse(f"<h1>500</h1><p>{line.replace('<', '&lt;')}</p>", status_code=500)

    app.add_middleware(Guard, token=token, max_body=max_upload, hosts=hosts)
    return app
