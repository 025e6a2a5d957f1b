"""Who may drive ``imugen serve``: the guards every request passes (issue 22).

The page starts workflows and serves their files, so on a shared workstation it must obey only
the user who started it, from their own browser tab:

Host allow-list
    The ``Host`` header must name this machine's loopback (``localhost``, any spelling of
    127.0.0.0/8 such as ``127.1``, ``[::1]``) or an address given with ``--host``. A page
    on another site cannot rebind its own name to 127.0.0.1 and read the answers (DNS
    rebinding): its requests carry its own name.
Access token
    ``imugen serve`` prints its address with a random token (``/?token=...``); the first
    visit turns it into an HttpOnly, SameSite=Strict cookie. Other users of the machine, who
    can reach its loopback port too, and other sites' pages, whose requests carry no cookie,
    are refused.
Cross-site requests
    Every state-changing request (POST) must be a form (``application/x-www-form-urlencoded``
    or ``multipart/form-data``; a ``text/plain`` POST, which a browser sends cross-site without
    asking, is refused), come from this page (``Origin``, else ``Referer``, equal to the page's
    own origin when the browser sends one) and carry the form token every page embeds.
Headers
    ``X-Frame-Options: DENY`` and a Content-Security-Policy that allows only this origin's
    scripts, styles and images and no framing; files from a run are served sandboxed.
"""

from __future__ import annotations

import hmac
import ipaddress
import re
import secrets
import socket
from urllib.parse import urlsplit

FORM_TYPES = ("application/x-www-form-urlencoded", "multipart/form-data")
"""Content types a state-changing request may have."""
CSP = (
    "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; "
    "connect-src 'self'; form-action 'self'; frame-ancestors 'none'; base-uri 'none'"
)
"""Content-Security-Policy of every page."""
HEADERS = {
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": CSP,
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "same-origin",
    "Cross-Origin-Opener-Policy": "same-origin",
    "Cross-Origin-Resource-Policy": "same-origin",
}
"""Headers of every response."""
_IPV4_TEXT = re.compile(r"^[0-9a-fx.]{1,40}$")


def split_host(host: str) -> str:
    """The name or address of a ``Host`` header, without its port: ``[::1]:80`` -> ``::1``."""
    h = host.strip().lower()
    if h.startswith("["):
        return h[1 : h.find("]")] if "]" in h else h
    if h.count(":") == 1:
        h = h.split(":", 1)[0]
    return h.rstrip(".") if h not in (".", "") else h


def is_loopback(host: str) -> bool:
    """True when ``host`` (a name or address, ``Host`` header or ``--host`` value) is this
    machine's loopback: ``localhost``, 127.0.0.0/8 in any spelling (``127.0.0.2``, ``127.1``,
    ``0x7f.1``, ``2130706433``), ``::1`` (bracketed or not, or IPv4-mapped)."""
    h = split_host(host)
    if h == "localhost":
        return True
    try:
        ip = ipaddress.ip_address(h)
    except ValueError:
        pass
    else:
        mapped = getattr(ip, "ipv4_mapped", None)
        return bool(ip.is_loopback or (mapped is not None and mapped.is_loopback))
    if not _IPV4_TEXT.match(h):
        return False
    try:
        return socket.inet_aton(h)[0] == 127
    except OSError:
        return False


class Guard:
    """The checks of one server: allowed hosts, access token, form token.

    Parameters
    ----------
    hosts : iterable of str
        Names or addresses besides the loopback ones that may appear in ``Host`` (the
        ``--host`` address the server listens on).
    access_token : str or None
        Token that admits a browser (None: no access token, for tests of other guards).
    """

    def __init__(self, hosts=(), access_token: str | None = None):
        self.hosts = {split_host(h) for h in hosts if h}
        self.access_token = access_token
        self.form_token = secrets.token_urlsafe(32)

    def host_allowed(self, host: str) -> bool:
        return is_loopback(host) or split_host(host) in self.hosts

    @staticmethod
    def cookie_name(host: str) -> str:
        """Cookie of the access token; per port (cookies are shared by all ports of a host)."""
        port = host.rsplit(":", 1)[1] if re.search(r":\d+$", host) else "80"
        return f"imugen_access_{port}"

    def token_ok(self, given: str | None) -> bool:
        return self.access_token is None or (
            given is not None and hmac.compare_digest(given.encode(), self.access_token.encode())
        )

    def form_ok(self, given: str | None) -> bool:
        return given is not None and hmac.compare_digest(given.encode(), self.form_token.encode())


def same_origin(request) -> bool:
    """True unless the browser names another origin (``Origin``, else ``Referer``)."""
    own = f"{request.scheme}://{request.host}".lower()
    origin = request.headers.get("Origin")
    if origin is not None:
        return origin.lower() == own
    referer = request.headers.get("Referer")
    if referer:
        parts = urlsplit(referer)
        return f"{parts.scheme}://{parts.netloc}".lower() == own
    return True  # neither: not a browser's cross-site request (the form token still applies)
