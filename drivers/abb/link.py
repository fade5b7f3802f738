"""One HTTP/1.1 link to a Robot Web Services 1.0 server: digest authentication, the
session cookies, an explicit timeout on every request, typed errors.

Standard library only (:mod:`http.client`): each request gets the time it may take (the
socket's timeout set to what is left), a reply that does not come in time closes the
connection (its late reply must not answer the next request) and raises
:class:`~drivers.errors.CommandTimeout`; a refused or dropped connection raises
:class:`~drivers.errors.ConnectionLost`. Nothing is retried here: the driver decides
(a read is asked again once, a move never).

Authentication (RWS 1.0): HTTP digest (RFC 7616, MD5, ``qop=auth``) in the realm
``validusers@robapi.abb``; the server then sets the session cookies (``-http-session-``,
``ABBCX``), sent back with every request so that the session, and the mastership it
holds, outlives a reconnection. Every request and reply is logged at DEBUG.
"""

from __future__ import annotations

import contextlib
import hashlib
import http.client
import json
import logging
import os
import re
import socket
import time
from urllib.parse import urlencode

from drivers.errors import CommandRejected, CommandTimeout, ConnectionLost, ProtocolError

from . import codec

log = logging.getLogger(__name__)

_PARAM = re.compile(r'(\w+)=(?:"([^"]*)"|([^,\s]*))')


def digest_params(header: str) -> dict[str, str]:
    """The parameters of a ``Digest ...`` header (``WWW-Authenticate`` or
    ``Authorization``)."""
    text = header.strip()
    if text[:6].lower() == "digest":
        text = text[6:]
    return {k: (q if q else u) for k, q, u in _PARAM.findall(text)}


def md5_hex(text: str) -> str:
    return hashlib.md5(text.encode("utf-8")).hexdigest()  # noqa: S324 - RFC 2617 digest


def digest_response(user: str, password: str, realm: str, method: str, uri: str, nonce: str,
                    nc: str, cnonce: str, qop: str = "auth") -> str:
    """The ``response`` of a digest authorization (MD5, ``qop=auth``)."""
    ha1 = md5_hex(f"{user}:{realm}:{password}")
    ha2 = md5_hex(f"{method}:{uri}")
    return md5_hex(f"{ha1}:{nonce}:{nc}:{cnonce}:{qop}:{ha2}")


class RwsLink:
    """HTTP requests to one RWS server, as ``user``.

    Parameters
    ----------
    device : str
        Who the errors name (the driver URL).
    host, port : str, int
    user, password : str
    idle_s : float
        A connection idle for longer is replaced before the next request (a controller
        closes idle keep-alive connections, and a request on one it closed would fail).
    """

    def __init__(self, device: str, host: str, port: int, user: str, password: str, *,
                 idle_s: float = 10.0) -> None:
        self.device = device
        self.host, self.port = host, port
        self.user, self.password = user, password
        self.idle_s = idle_s
        self._conn: http.client.HTTPConnection | None = None
        self._last_use = 0.0
        self._cookies: dict[str, str] = {}
        self._challenge: dict[str, str] | None = None
        self._nc = 0

    # -- the connection -----------------------------------------------------------------

    def open(self, timeout: float) -> None:
        """Open the TCP connection (ConnectionLost when refused or unreachable,
        CommandTimeout when it does not open in time)."""
        self.drop()
        conn = http.client.HTTPConnection(self.host, self.port, timeout=max(timeout, 0.01))
        try:
            conn.connect()
        except TimeoutError as e:
            raise CommandTimeout(self.device, "connect", f"no answer within {timeout:g} s") from e
        except OSError as e:
            raise ConnectionLost(self.device, "connect",
                                 f"no RWS server at {self.host}:{self.port}: {e}") from e
        with contextlib.suppress(OSError):  # no Nagle: every request is a whole message
            conn.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._conn, self._last_use = conn, time.monotonic()

    def drop(self) -> None:
        """Close the TCP connection (the session cookies are kept)."""
        conn, self._conn = self._conn, None
        if conn is not None:
            with contextlib.suppress(OSError):
                conn.close()

    def forget_session(self) -> None:
        """Forget the session (cookies and the server's digest challenge)."""
        self._cookies.clear()
        self._challenge = None
        self._nc = 0

    @property
    def has_session(self) -> bool:
        """Whether the server gave this link a session (its cookies)."""
        return bool(self._cookies)

    @property
    def is_open(self) -> bool:
        """Whether a TCP connection is open (none after a lost or timed-out request)."""
        return self._conn is not None

    # -- requests -----------------------------------------------------------------------

    def _authorization(self, method: str, uri: str) -> str | None:
        ch = self._challenge
        if ch is None:
            return None
        self._nc += 1
        nc, cnonce = f"{self._nc:08x}", os.urandom(8).hex()
        realm, nonce = ch.get("realm", codec.REALM), ch.get("nonce", "")
        resp = digest_response(self.user, self.password, realm, method, uri, nonce, nc, cnonce)
        parts = [f'username="{self.user}"', f'realm="{realm}"', f'nonce="{nonce}"',
                 f'uri="{uri}"', f'response="{resp}"', 'algorithm="MD5"', 'qop="auth"',
                 f"nc={nc}", f'cnonce="{cnonce}"']
        if "opaque" in ch:
            parts.append(f'opaque="{ch["opaque"]}"')
        return "Digest " + ", ".join(parts)

    def _send(self, method: str, uri: str, body: bytes | None, timeout: float,
              command: str) -> tuple[http.client.HTTPResponse, bytes]:
        if self._conn is None or time.monotonic() - self._last_use > self.idle_s:
            self.open(timeout)
        conn = self._conn
        assert conn is not None
        headers = {"Accept": "application/json", "Connection": "keep-alive"}
        if body is not None:
            headers["Content-Type"] = "application/x-www-form-urlencoded"
        if self._cookies:
            headers["Cookie"] = "; ".join(f"{k}={v}" for k, v in self._cookies.items())
        auth = self._authorization(method, uri)
        if auth is not None:
            headers["Authorization"] = auth
        try:
            if conn.sock is not None:
                conn.sock.settimeout(max(timeout, 0.01))
            else:
                conn.timeout = max(timeout, 0.01)
            conn.request(method, uri, body=body, headers=headers)
            resp = conn.getresponse()
            data = resp.read()
        except TimeoutError as e:
            self.drop()  # its late reply must not answer the next request
            log.info("robot %s: %s: no answer within %.3g s", self.device, command, timeout)
            raise CommandTimeout(self.device, command,
                                 f"no answer within {timeout:.3g} s") from e
        except (OSError, http.client.HTTPException) as e:
            self.drop()
            log.info("robot %s: %s: link lost (%s: %s)", self.device, command,
                     type(e).__name__, e)
            raise ConnectionLost(self.device, command,
                                 f"link lost ({type(e).__name__}: {e})") from e
        self._last_use = time.monotonic()
        for name, value in resp.getheaders():
            if name.lower() == "set-cookie":
                k, _, v = value.split(";", 1)[0].partition("=")
                if k.strip():
                    self._cookies[k.strip()] = v.strip()
        if resp.getheader("Connection", "").lower() == "close" or resp.will_close:
            self.drop()
        return resp, data

    def request(self, method: str, path: str, form: dict[str, str] | None = None, *,
                timeout: float, command: str = "") -> tuple[int, dict | None]:
        """``method`` ``path`` (JSON asked for; ``form``: a form post), answered within
        ``timeout`` s: (HTTP status, the JSON answer or None). Authenticates when asked to
        (one digest challenge per request)."""
        command = command or f"{method} {path.split('?')[0]}"
        deadline = time.monotonic() + timeout
        uri = "/" + codec.with_json(path)
        body = urlencode(form).encode() if form is not None else None
        if log.isEnabledFor(logging.DEBUG):
            log.debug("robot %s: > %s %s%s", self.device, method, uri,
                      "".join(f" {k}={v}" for k, v in (form or {}).items()))
        for attempt in (1, 2):
            left = deadline - time.monotonic()
            if left <= 0:
                raise CommandTimeout(self.device, command, f"no answer within {timeout:.3g} s")
            resp, data = self._send(method, uri, body, left, command)
            if resp.status != 401:
                break
            challenge = resp.getheader("WWW-Authenticate", "")
            if attempt == 2 or not challenge.lower().startswith("digest"):
                raise CommandRejected(self.device, command,
                                      f"authentication refused for user {self.user!r}: check "
                                      "the user and password of the URL")
            self._cookies.clear()  # a stale session: authenticate again
            self._challenge, self._nc = digest_params(challenge), 0
        doc = None
        if data:
            ctype = (resp.getheader("Content-Type") or "").split(";")[0].strip()
            if ctype == "application/json":
                try:
                    doc = json.loads(data)
                except ValueError as e:
                    raise ProtocolError(self.device, command, f"bad JSON: {data[:80]!r}") from e
        if log.isEnabledFor(logging.DEBUG):
            log.debug("robot %s: < %d %s", self.device, resp.status, _decoded(doc, data))
        return resp.status, doc


def _decoded(doc: dict | None, data: bytes) -> str:
    """An answer in a line: each item's fields (``_type: key=value ...``), an error's code
    and message, else the raw text."""
    if doc is None:
        return data[:200].decode("utf-8", "replace") if data else "(no content)"
    code, msg = codec.status_of(doc)
    if code or msg:
        return f"error {code}: {msg}"
    return "; ".join(" ".join([str(i.get("_type", "?")) + ":"]
                              + [f"{k}={v}" for k, v in i.items() if not k.startswith("_")])
                     for i in codec.states(doc)) or "(no items)"
