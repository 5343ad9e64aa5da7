"""Who may open ``mirobot view``: the per-run secret and the origin, checked at the handshake.

viser serves its page and its websocket on one port through ``websockets``' ``serve`` and lets
anyone connect. :func:`guarded_serve` hands every request of the server built inside it to
:class:`Gate` first (``process_request``: the HTTP handshake, before any viser message is read
or sent). The gate lets a request through only when

- its ``Host`` is this server as the URL names it (a loopback name and the port), so that a
  page of another site resolved to 127.0.0.1 (DNS rebinding) is refused; with ``--allow-remote``
  any host name (the secret still applies);
- it carries the secret: ``?token=SECRET`` (the URL the command prints) or the cookie the page
  got from that URL (``HttpOnly``, ``SameSite=Strict``, named after the port so that two views
  on one machine keep theirs);
- for the websocket, its ``Origin`` is this server itself (``http://`` + the ``Host``): a page
  of another origin (another local port, a ``file://`` page, a copy of the client) is refused
  even though the browser sends it the cookie (cookies do not tell ports apart).

Everything refused is answered ``403`` with one line saying why, also printed on stderr.
"""

from __future__ import annotations

import contextlib
import hmac
import http
import secrets
import sys
from collections.abc import Callable, Iterator
from http.cookies import CookieError, SimpleCookie
from typing import TYPE_CHECKING, Any, Final
from urllib.parse import parse_qs, urlsplit

from websockets.datastructures import Headers
from websockets.http11 import Request, Response

from mirobot_async.errors import MirobotUsageError

if TYPE_CHECKING:
    import viser

__all__ = [
    "LOOPBACK_HOSTS",
    "Gate",
    "guarded_serve",
    "is_loopback",
    "serve_guarded",
    "stop_server",
]

LOOPBACK_HOSTS: Final = frozenset({"127.0.0.1", "localhost", "::1"})
_HELP: Final = "open the URL that mirobot view printed (it carries this run's secret)"

ProcessRequest = Callable[[Any, Request], Any]


def is_loopback(host: str) -> bool:
    """``127.0.0.0/8``, ``localhost`` or ``::1``."""
    host = host.strip("[]").lower()
    return host in LOOPBACK_HOSTS or host.startswith("127.")


class Gate:
    """The secret of one run and the checks of every request (see the module)."""

    def __init__(self, *, allow_remote: bool = False, token: str | None = None) -> None:
        self.token = token or secrets.token_urlsafe(24)
        self.allow_remote = allow_remote
        self.installed = False
        """Set once viser's server was built with the gate in front (checked by the command)."""
        self.refused: list[str] = []
        """Why each refused request was refused (newest last; for the log and the tests)."""

    def cookie_name(self, port: int) -> str:
        return f"mirobot-view-{port}"

    def url(self, host: str, port: int) -> str:
        """The page's URL with the secret (what the command prints)."""
        shown = f"[{host}]" if ":" in host else host
        return f"http://{shown}:{port}/?token={self.token}"

    def check(self, request: Request, port: int) -> str | None:
        """Why ``request`` is refused, or ``None`` when it may go on."""
        host = request.headers.get("Host", "")
        name, _, host_port = host.rpartition(":")
        if not host or host_port != str(port):
            return f"Host {host!r} is not this server"
        if not self.allow_remote and not is_loopback(name):
            return f"Host {host!r} is not a loopback address (use the printed URL)"
        if not self._has_secret(request, port):
            return f"no secret: {_HELP}"
        if request.headers.get("Upgrade", "").lower() == "websocket":
            origin = request.headers.get("Origin")
            if origin is None or origin.lower() != f"http://{host}".lower():
                return f"Origin {origin!r} is not this page (http://{host})"
        return None

    def _has_secret(self, request: Request, port: int) -> bool:
        query = parse_qs(urlsplit(request.path).query)
        for given in query.get("token", []):
            if hmac.compare_digest(given.encode(), self.token.encode()):
                return True
        cookie = SimpleCookie()
        for header in request.headers.get_all("Cookie"):
            with contextlib.suppress(CookieError):
                cookie.load(header)
        morsel = cookie.get(self.cookie_name(port))
        return morsel is not None and hmac.compare_digest(
            morsel.value.encode(), self.token.encode()
        )

    def wrap(self, inner: ProcessRequest | None) -> ProcessRequest:
        """viser's ``process_request`` behind the gate; the page's answer sets the cookie."""
        self.installed = True

        def process_request(connection: Any, request: Request) -> Any:
            port = int(connection.local_address[1])
            why = self.check(request, port)
            if why is not None:
                self.refused.append(why)
                path = request.path.partition("?")[0]
                print(f"mirobot: view: refused {path}: {why}", file=sys.stderr, flush=True)
                body = f"mirobot view: refused: {why}\n".encode()
                headers = Headers({"Content-Type": "text/plain; charset=utf-8"})
                headers["Content-Length"] = str(len(body))
                return Response(http.HTTPStatus.FORBIDDEN, "Forbidden", headers, body)
            response = None if inner is None else inner(connection, request)
            if isinstance(response, Response) and "token=" in request.path:
                response.headers["Set-Cookie"] = (
                    f"{self.cookie_name(port)}={self.token}; Path=/; HttpOnly; SameSite=Strict"
                )
            return response

        return process_request


@contextlib.contextmanager
def guarded_serve(gate: Gate) -> Iterator[None]:
    """While inside, a ``websockets`` server started (viser's) has ``gate`` in front of its
    ``process_request``. viser calls ``serve`` in its own thread before its constructor returns,
    so building the ``ViserServer`` inside this block is enough; ``gate.installed`` says it
    happened (the command refuses to serve otherwise)."""
    import websockets.asyncio.server as server_module

    original = server_module.serve

    def serve(*args: Any, **kwargs: Any) -> Any:
        kwargs["process_request"] = gate.wrap(kwargs.get("process_request"))
        return original(*args, **kwargs)

    server_module.serve = serve  # type: ignore[assignment,misc]
    try:
        yield
    finally:
        server_module.serve = original  # type: ignore[misc]


def serve_guarded(host: str, port: int, *, allow_remote: bool) -> tuple[viser.ViserServer, str]:
    """A viser server on ``host``:``port`` (0: a free one) with a new :class:`Gate` in front,
    and the URL that opens it (with the gate's secret; a wildcard host shown as
    ``127.0.0.1``). Fails closed: when the gate could not be put in front, the server is
    stopped and :class:`MirobotUsageError` says so. viser's banner goes to stderr."""
    import sys

    import viser

    gate = Gate(allow_remote=allow_remote)
    with contextlib.redirect_stdout(sys.stderr), guarded_serve(gate):
        server = viser.ViserServer(host=host, port=port, verbose=False)
    if not gate.installed:
        stop_server(server)
        raise MirobotUsageError(
            f"viser {viser.__version__} serves its websocket in a way this version cannot "
            "guard; refusing to serve the page"
        )
    shown = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
    return server, gate.url(shown, server.get_port())


def stop_server(server: viser.ViserServer) -> None:
    """Stop ``server`` (viser's "Server stopped" goes to stderr)."""
    import sys

    with contextlib.redirect_stdout(sys.stderr):
        server.stop()
