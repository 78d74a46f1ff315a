"""Who may drive a ``psvs serve`` server: the page it serves, and clients holding its per-run token.

A local web server is reachable from every web page the user opens: a page on ``evil.example`` may post to
``http://127.0.0.1:8000`` (a "simple request" -- a form or a ``text/plain`` fetch -- needs no preflight), or
point its own name at 127.0.0.1 and read the answers as its own (DNS rebinding). :class:`Guard` (ASGI
middleware, outside every route and the static files) refuses both, as Jupyter's and VS Code's local servers do:

1. **Host** (every request): the ``Host`` header must name the server -- one of :attr:`Access.names` and the
   port the connection arrived on, or a ``NAME:PORT`` given as is. A wildcard bind (0.0.0.0, ::) also answers
   to every IP address of this machine. Anything else: 400. A rebinding page's requests carry its own name.
2. **Origin** (every method but GET, HEAD, OPTIONS): ``Origin``, when sent, must be the server's own (http, an
   allowed name, the port the request reached); ``Sec-Fetch-Site``, when sent, ``same-origin`` or ``none``.
   A request with neither (curl, a script) must carry the right token: ``Authorization: Bearer TOKEN`` or
   the cookie set when the page is opened as ``/?token=TOKEN``. Else: 403.
3. **Body type** (the same methods, with a body): ``application/json``, or for an upload
   (:data:`UPLOAD_PATHS`) an image type of :data:`UPLOAD_TYPES` (its bytes say which format it is). The
   types a browser sends across origins without asking (``text/plain``, forms)
   never reach a route: 415.

The page served by the server needs nothing: its requests carry its own origin. Refusals are JSON
``{"detail": "..."}`` in one line, sent before the body is read.

Examples
--------
>>> split_host("127.0.0.1:8000"), split_host("[::1]:80"), split_host("Localhost."), split_host("a b")
(('127.0.0.1', 8000), ('::1', 80), ('localhost', None), None)
>>> access = Access.for_bind("127.0.0.1", token="t")
>>> sorted(access.names)
['127.0.0.1', '::1', 'localhost']
>>> access.host_allowed("localhost:8000", 8000), access.host_allowed("attacker.example:8000", 8000)
(True, False)
"""
from __future__ import annotations

import functools
import hmac
import ipaddress
import re
import secrets
import socket
from dataclasses import dataclass, field
from http.cookies import CookieError, SimpleCookie
from urllib.parse import parse_qs

from psvs.web.limits import reply_json

__all__ = ["LOOPBACK", "UPLOAD_PATHS", "UPLOAD_TYPES", "VIDEO_PATHS", "VIDEO_TYPES", "Access", "Guard", "split_host"]

#: The names of this machine's loopback interface.
LOOPBACK = frozenset({"localhost", "127.0.0.1", "::1"})
#: Methods that read: no origin check, no body.
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
#: Paths whose body is an image file (``Content-Type`` one of UPLOAD_TYPES); every other body is JSON.
UPLOAD_PATHS = frozenset({"/api/upload"})
#: The types an upload may carry: the image formats psvs reads (none of them one a browser sends to another
#: origin without asking it first).
UPLOAD_TYPES = ("image/png", "image/jpeg", "image/bmp", "image/tiff", "image/x-portable-anymap",
                "image/x-portable-graymap", "image/x-portable-pixmap", "image/x-portable-bitmap")
#: Paths whose body is a video file (``Content-Type`` one of VIDEO_TYPES: the page sends a file's own type, or
#: application/octet-stream when the browser knows none; none of them CORS-simple).
VIDEO_PATHS = frozenset({"/api/source/video"})
VIDEO_TYPES = ("video/x-msvideo", "video/avi", "video/msvideo", "video/x-matroska", "video/mp4", "video/quicktime",
               "video/webm", "application/octet-stream")
#: ``Sec-Fetch-Site`` values of a request the page itself made, or the user typed.
SAME_SITE_FETCH = frozenset({"same-origin", "none"})
#: Longest quoted header in a refusal (characters).
MAX_QUOTE = 80

_NAME = re.compile(r"[a-z0-9_]([a-z0-9_-]*[a-z0-9_])?(\.[a-z0-9_]([a-z0-9_-]*[a-z0-9_])?)*")


def split_host(value: str) -> tuple[str, int | None] | None:
    """A ``Host`` header, an ``Origin``'s host[:port] or an ``--allow-host`` value as (name, port): the name
    lower-case, an IP address in its short form without an IPv6 address's brackets, a DNS name without its
    final dot; port None when not given. None when malformed. A bare IPv6 address (``::1``) is read as one."""
    value = value.strip().lower()
    if _is_ip(value):
        return str(ipaddress.ip_address(value)), None
    m = re.fullmatch(r"\[([0-9a-f:.]+)\](?::(\d{1,5}))?|([^:\[\]]+)(?::(\d{1,5}))?", value)
    if m is None:
        return None
    name, port = (m.group(1), m.group(2)) if m.group(1) else (m.group(3).removesuffix("."), m.group(4))
    if _is_ip(name):
        name = str(ipaddress.ip_address(name))
    elif m.group(1) or _NAME.fullmatch(name) is None:
        return None
    port = None if port is None else int(port)
    return None if port is not None and not 0 < port <= 65535 else (name, port)


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


@functools.lru_cache(maxsize=256)
def _is_local_address(name: str) -> bool:
    """Whether ``name`` is an IP address of one of this machine's interfaces: only those can be bound."""
    try:
        ip = ipaddress.ip_address(name)
    except ValueError:
        return False
    if ip.is_loopback:
        return True
    family = socket.AF_INET6 if ip.version == 6 else socket.AF_INET
    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.bind((name, 0))
    except OSError:
        return False
    return True


@dataclass(frozen=True)
class Access:
    """The names a server answers to and its per-run token (:class:`Guard`'s rules).

    Attributes
    ----------
    names : frozenset of str
        Lower-case host names and IP addresses (IPv6 without brackets), allowed with the port the request
        arrived on.
    token : str
        The per-run secret of clients that are not the page (``Authorization: Bearer``, or the cookie).
    pairs : frozenset of (str, int)
        Names allowed with another port (``--allow-host localhost:9000``: a tunnel or port forward).
    any_local_address : bool
        Also every IP address of this machine (a wildcard bind: 0.0.0.0 or ::).
    """

    names: frozenset[str]
    token: str = field(repr=False)
    pairs: frozenset[tuple[str, int]] = frozenset()
    any_local_address: bool = False

    def __post_init__(self):
        if not self.token:
            raise ValueError("token must be a non-empty string")

    @classmethod
    def for_bind(cls, host: str, address: str | None = None, allow: tuple[str, ...] = (),
                 token: str | None = None) -> Access:
        """The access of a server bound to ``host`` (as the user gave it) at ``address`` (the IP address it
        resolved to; default ``host``), answering also to ``allow`` (names or ``NAME:PORT``).

        A loopback bind answers to the loopback names, a wildcard bind (0.0.0.0, ::) to those, this machine's
        name (``gethostname()``, and ``NAME.local`` of mDNS) and its IP addresses; another bind to ``host`` and
        ``address``. ValueError names an ``allow`` entry that is not a host name, an IP address or NAME:PORT.
        The token is a new random one unless given."""
        given = split_host(host) if host else ("0.0.0.0", None)
        if given is None or given[1] is not None:
            raise ValueError(f"--host must be a host name or an IP address, got {host!r}")
        names = {given[0], *([] if address is None else [str(ipaddress.ip_address(address))])}
        wildcard = any(_is_ip(n) and ipaddress.ip_address(n).is_unspecified for n in names)
        if wildcard:
            me = socket.gethostname().lower()
            names |= {me, f"{me.split('.')[0]}.local"}
        if wildcard or "localhost" in names or any(_is_ip(n) and ipaddress.ip_address(n).is_loopback for n in names):
            names |= LOOPBACK
        pairs = set()
        for entry in allow:
            parsed = split_host(entry)
            if parsed is None:
                raise ValueError(f"--allow-host must be a host name, an IP address or NAME:PORT, got {entry!r}")
            if parsed[1] is None:
                names.add(parsed[0])
            else:
                pairs.add(parsed)
        return cls(frozenset(names), token or secrets.token_urlsafe(32), frozenset(pairs), wildcard)

    def host_allowed(self, host: str, port: int | None) -> bool:
        """Whether a ``Host`` header (or an ``Origin``'s host[:port]) names this server reached on ``port``
        (None: unknown, any port). A header without a port names port 80."""
        parsed = split_host(host)
        if parsed is None:
            return False
        name, named_port = parsed[0], 80 if parsed[1] is None else parsed[1]
        if (name, named_port) in self.pairs:
            return True
        if port is not None and named_port != port:
            return False
        return name in self.names or (self.any_local_address and _is_local_address(name))

    def token_matches(self, token: str) -> bool:
        """Whether ``token`` is this server's session token (compared in constant time)."""
        return hmac.compare_digest(token.encode(), self.token.encode())


class Guard:
    """ASGI middleware applying :class:`Access`'s rules (the module's docstring) to every request before the
    app sees it; the page opened as ``/?token=TOKEN`` gets the token as a cookie and is sent to ``/``."""

    def __init__(self, app, access: Access):
        self.app, self.access = app, access

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        headers = _headers(scope)
        port = (scope.get("server") or (None, None))[1]
        status, detail = self.refusal(scope, headers, port)
        if status:
            if scope["type"] == "websocket":
                return await send({"type": "websocket.close", "code": 1008, "reason": detail[:120]})
            return await reply_json(send, status, detail)
        if scope["type"] == "http" and scope["method"] == "GET" and scope["path"] == "/":
            token = parse_qs(scope.get("query_string", b"").decode("latin-1")).get("token")
            if token:
                return await self._open_with_token(send, token[0], port)
        return await self.app(scope, receive, send)

    def refusal(self, scope, headers: dict[str, str], port: int | None) -> tuple[int, str]:
        """(status, one-line reason) of a request the rules refuse, (0, "") of one they let through."""
        host = headers.get("host", "")
        if not self.access.host_allowed(host, port):
            return 400, (f"Host {_quote(host)} is not this server's address (psvs serve --allow-host NAME "
                         f"adds a name)" if host else "no Host header")
        if scope["type"] == "http" and scope["method"] in SAFE_METHODS:
            return 0, ""
        status, detail = self._origin_refusal(headers, host, port)
        if status or scope["type"] == "websocket":
            return status, detail
        return self._type_refusal(scope, headers)

    def _origin_refusal(self, headers: dict[str, str], host: str, port: int | None) -> tuple[int, str]:
        origin, fetch_site = headers.get("origin"), headers.get("sec-fetch-site")
        if origin is not None and not self._own_origin(origin, host, port):
            return 403, f"cross-origin request refused: Origin {_quote(origin)} is not this server's"
        if fetch_site is not None and fetch_site.strip().lower() not in SAME_SITE_FETCH:
            return 403, f"cross-origin request refused: Sec-Fetch-Site is {_quote(fetch_site)}"
        if origin is not None or fetch_site is not None:
            return 0, ""                      # the page itself (a cookie of an earlier run does not matter)
        token = _bearer(headers.get("authorization"))
        if token is None:
            token = _cookie(headers.get("cookie"), cookie_name(port))
        if token is None:
            return 403, ("a request from outside the page needs the token psvs serve printed: "
                         "Authorization: Bearer TOKEN")
        if not self.access.token_matches(token):
            return 403, "wrong token: use the one psvs serve printed (Authorization: Bearer TOKEN)"
        return 0, ""

    def _own_origin(self, origin: str, host: str, port: int | None) -> bool:
        """An ``Origin`` of this server: http, an allowed name, and the port the Host header names (the port
        the browser reached; Origin omits the scheme's default one, as Host does)."""
        m = re.fullmatch(r"http://([^/?#@]+)", origin.strip())
        if m is None:
            return False
        own, theirs = split_host(host), split_host(m.group(1))
        return (own is not None and theirs is not None and (own[1] or 80) == (theirs[1] or 80)
                and self.access.host_allowed(m.group(1), port))

    @staticmethod
    def _type_refusal(scope, headers: dict[str, str]) -> tuple[int, str]:
        if headers.get("content-length", "0").strip() in ("", "0") and "transfer-encoding" not in headers:
            return 0, ""                      # no body, no type to check
        path = scope["path"]
        wanted = (UPLOAD_TYPES if path in UPLOAD_PATHS else VIDEO_TYPES if path in VIDEO_PATHS
                  else ("application/json",))
        given = headers.get("content-type", "").split(";")[0].strip().lower()
        if given not in wanted:
            kind = "an image" if path in UPLOAD_PATHS else "a video"
            what = f"{kind} ({', '.join(wanted[:5])}, ...)" if len(wanted) > 1 else wanted[0]
            return 415, (f"{scope['method']} {scope['path'][:MAX_QUOTE]} takes {what}, got "
                         f"{_quote(given) if given else 'no Content-Type'}")
        return 0, ""

    async def _open_with_token(self, send, token: str, port: int | None) -> None:
        """``/?token=TOKEN``: the token as a cookie (HttpOnly, SameSite=Strict, this server's port) and a
        redirect to ``/``, so the address bar and the history do not keep it; a wrong token gets 403."""
        if not self.access.token_matches(token):
            return await reply_json(send, 403, "wrong token: use the one psvs serve printed")
        cookie = f"{cookie_name(port)}={self.access.token}; Path=/; HttpOnly; SameSite=Strict"
        await send({"type": "http.response.start", "status": 303,
                    "headers": [(b"location", b"/"), (b"set-cookie", cookie.encode()), (b"content-length", b"0"),
                                (b"cache-control", b"no-store")]})
        await send({"type": "http.response.body", "body": b""})


def cookie_name(port: int | None) -> str:
    """The token's cookie, one per port: cookies do not tell ports apart, two servers' would collide."""
    return f"psvs-token-{port or 80}"


def _headers(scope) -> dict[str, str]:
    """The request's headers, lower-case names; a repeated one keeps its first value (Host, Origin)."""
    out: dict[str, str] = {}
    for key, value in scope.get("headers") or ():
        out.setdefault(key.decode("latin-1").lower(), value.decode("latin-1"))
    return out


def _bearer(value: str | None) -> str | None:
    if value is None:
        return None
    scheme, _, token = value.strip().partition(" ")
    return token.strip() if scheme.lower() == "bearer" else ""


def _cookie(value: str | None, name: str) -> str | None:
    if not value:
        return None
    try:
        jar = SimpleCookie(value)
    except CookieError:
        return None
    return jar[name].value if name in jar else None


def _quote(value: str) -> str:
    """A header value quoted in a refusal: printable ASCII, at most :data:`MAX_QUOTE` characters."""
    text = "".join(c if " " <= c <= "~" else "?" for c in value)
    return repr(text[:MAX_QUOTE] + ("..." if len(text) > MAX_QUOTE else ""))
