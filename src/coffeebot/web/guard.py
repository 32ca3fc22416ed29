"""What a request must pass before any handler sees it, and the headers every answer carries.

* **The Host it names.** A web page elsewhere can point its own name at the robot's address
  (DNS rebinding) and then call the API as if it were the robot's own page; its requests
  name that other host. Only IP addresses, ``localhost``, this machine's own names and the
  names in ``[web] allowed_hosts`` are answered.
* **Cross-site writes.** A form or script on another site can make a browser post to the
  robot (cross-site request forgery). A browser says where a request comes from: a
  ``Sec-Fetch-Site`` other than ``same-origin`` or ``none``, or else an ``Origin`` that is
  not this host, is refused for every method that changes something. Clients that are not
  browsers send neither and are not affected (the approach of Go's
  ``http.CrossOriginProtection``).
* **Headers on every answer**, streams and files included: the content security policy,
  ``nosniff``, no referrer, and ``Cache-Control: no-store`` on everything but the static
  files (order pages and answers carry names and the order's key).
"""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Iterable
from urllib.parse import urlsplit

from aiohttp import web

SECURITY_HEADERS = {
    # No inline script anywhere, so injected markup could not run even if it got through.
    "Content-Security-Policy": (
        "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
        "img-src 'self' data:; object-src 'none'; base-uri 'none'; frame-ancestors 'none'"
    ),
    "X-Content-Type-Options": "nosniff",
    # An order's key in its URL is what lets its holder act on it: never send it elsewhere.
    "Referrer-Policy": "no-referrer",
}

CACHEABLE_PREFIX = "/static/"

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def _hostname(host: str) -> str:
    """The name in a Host header, without its port, brackets or trailing dot, lower case."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[1:].partition("]")[0]
    return host.rpartition(":")[0] if host.count(":") == 1 else host.rstrip(".")


def _is_address(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


class AllowedHosts:
    """The names this server answers to, besides IP addresses (no DNS, so no rebinding)."""

    def __init__(self, extra: Iterable[str] = ()) -> None:
        machine = socket.gethostname().lower()
        names = {"localhost", machine, f"{machine}.local", socket.getfqdn().lower()}
        self.names = frozenset(_hostname(n) for n in (*names, *extra) if n)

    def allows(self, host: str | None) -> bool:
        """Whether a request naming ``host`` is answered (no Host header: not a browser)."""
        if host is None:
            return True
        name = _hostname(host).rstrip(".")
        return _is_address(name) or name in self.names or name.endswith(".localhost")


def cross_site(request: web.Request) -> bool:
    """Whether a browser sent this request from another site's page."""
    site = request.headers.get("Sec-Fetch-Site")
    if site is not None:
        return site not in ("same-origin", "none")
    origin = request.headers.get("Origin")
    if origin is None:
        return False
    return urlsplit(origin).netloc.lower() != request.headers.get("Host", "").lower()


def refusal(request: web.Request, allowed: AllowedHosts) -> tuple[int, str] | None:
    """Why the request is refused before its handler (status, message), or None."""
    host = request.headers.get("Host")
    if not allowed.allows(host):
        return 421, f"this server does not answer to the name {_hostname(host or '')!r}"
    if request.method not in SAFE_METHODS and cross_site(request):
        return 403, "a request from another site's page is refused"
    return None


async def add_headers(request: web.Request, response: web.StreamResponse) -> None:
    """``on_response_prepare``: every answer gets the security headers, streams too."""
    response.headers.update(SECURITY_HEADERS)
    if not request.path.startswith(CACHEABLE_PREFIX):
        response.headers["Cache-Control"] = "no-store"
