"""The simulated ABB controller's Robot Web Services 1.0: an HTTP server over a
:class:`~sim_drivers.abb_controller.SimIrc5`.

Standard library only (:class:`http.server.ThreadingHTTPServer`, HTTP/1.1 keep-alive).
RWS 1.0's authentication: HTTP digest (MD5, ``qop=auth``, realm
``validusers@robapi.abb``) for the factory user ``Default User`` / ``robotics``; an
authenticated client gets the session cookies ``-http-session-`` and ``ABBCX``, and a
request carrying them needs no digest again (``logout`` ends the session and releases
its mastership). The resources are those of :mod:`drivers.abb.codec`, in the JSON of
``?json=1`` (an unknown one: 404). The real client ``abb-robot-client`` is served
(tests/sim_drivers/test_rws_server.py).

Wire faults per request (:mod:`sim_drivers.faults`): ``drop`` closes the connection
instead of answering, ``slow`` holds the answer back ``delay`` s; the state faults are
the controller's (:mod:`sim_drivers.abb_controller`).
"""

from __future__ import annotations

import contextlib
import http.server
import json
import logging
import os
import socket
import threading
from http.cookies import SimpleCookie
from urllib.parse import parse_qs, unquote, urlsplit

import numpy as np

from drivers.abb import codec as C
from drivers.abb.link import digest_params, digest_response
from sim_drivers.abb_controller import RwsRefused, SimIrc5
from sim_drivers.cell import SimCell
from sim_drivers.faults import FaultInjector

log = logging.getLogger(__name__)

#: what the simulated controller says of itself: a virtual controller, cellcal's
CTRL_NAME, CTRL_TYPE = "cellcal-sim", "Virtual Controller"
RW_VERSION, RW_VERSION_NAME = "6.15.0000", "6.15.00.00 cellcal sim"
SESSION_COOKIE, ABBCX = "-http-session-", "ABBCX"


class RwsServer:
    """RWS 1.0 server of ``cell``'s robot on ``host:port`` (0: a free one).

    ``controller`` (a :class:`SimIrc5`) is the state behind it: the operator's hooks
    (motors, mastership, operating mode) are there. ``user``/``password``: the one RWS
    user it knows.
    """

    def __init__(self, cell: SimCell, *, faults: FaultInjector | None = None,
                 host: str = "127.0.0.1", port: int = 0, user: str = C.DEFAULT_USER,
                 password: str = C.DEFAULT_PASSWORD) -> None:
        self.cell = cell
        self.faults = faults if faults is not None else (cell.faults or FaultInjector())
        self.controller = SimIrc5(cell, self.faults)
        self.host, self.port = host, port
        self.user, self.password = user, password
        self.sessions: set[str] = set()
        self.nonces: set[str] = set()
        self._httpd: http.server.ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._conns: set[socket.socket] = set()
        self._conns_lock = threading.Lock()

    @property
    def url(self) -> str:
        """The driver URL (``?joints=N`` when the arm has not 6)."""
        n = self.cell.n_joints
        return f"abb://{self.host}:{self.port}" + (f"?joints={n}" if n != 6 else "")

    @property
    def base_url(self) -> str:
        """What ``abb_robot_client.rws.RWS`` is given."""
        return f"http://{self.host}:{self.port}"

    def start(self) -> RwsServer:
        self._stop.clear()
        server = self

        class Handler(_Handler):
            rws = server

        httpd = _Httpd((self.host, self.port), Handler)
        self.port = httpd.server_address[1]
        self._httpd = httpd
        self._thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.05},
                                        name="sim-rws", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving and close every connection (idempotent)."""
        self._stop.set()
        httpd, self._httpd = self._httpd, None
        if httpd is not None:
            httpd.shutdown()
            httpd.server_close()
        with self._conns_lock:
            conns = list(self._conns)
        for s in conns:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None

    def __enter__(self) -> RwsServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def drop_all(self) -> None:
        """Close every client connection (sessions stay)."""
        with self._conns_lock:
            conns = list(self._conns)
        for s in conns:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)

    # -- authentication ---------------------------------------------------------------------

    def new_nonce(self) -> str:
        nonce = os.urandom(16).hex()
        self.nonces.add(nonce)
        return nonce

    def check_digest(self, method: str, uri: str, header: str) -> bool:
        p = digest_params(header)
        if p.get("username") != self.user or p.get("nonce") not in self.nonces:
            return False
        if p.get("uri") != uri:
            return False
        want = digest_response(self.user, self.password, C.REALM, method, p["uri"],
                               p["nonce"], p.get("nc", ""), p.get("cnonce", ""),
                               p.get("qop", "auth"))
        return p.get("response") == want


class _Httpd(http.server.ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def handle_error(self, request, client_address) -> None:  # a client gone: not news
        log.debug("rws server: connection from %s ended with an error", client_address,
                  exc_info=True)


def _jointtarget_items(q_rad: np.ndarray) -> dict:
    deg = list(np.rad2deg(q_rad)) + [0.0] * (6 - len(q_rad))
    item = {"_type": "ms-jointtarget", "_title": "ROB_1"}
    item.update({f"rax_{i + 1}": f"{v:.6f}" for i, v in enumerate(deg)})
    item.update({f"eax_{c}": "9E+09" for c in "abcdef"})
    return item


def _symbol_name(rest: str) -> str:
    """The symbol of ``MODULE/name`` or ``name`` (a task-global PERS); RwsRefused for a
    module the task does not have."""
    module, _, name = rest.rpartition("/")
    if module not in ("", C.MODULE):
        raise RwsRefused(400, "not_found", f"symbol RAPID/{C.TASK}/{rest} not found: no "
                         f"module {module} in {C.TASK}")
    return name


class _Handler(http.server.BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    disable_nagle_algorithm = True  # headers and body go in two writes
    server_version = "cellcal-sim-RWS/1.0"
    rws: RwsServer

    def setup(self) -> None:
        super().setup()
        with self.rws._conns_lock:
            self.rws._conns.add(self.connection)

    def finish(self) -> None:
        with contextlib.suppress(OSError):
            super().finish()
        with self.rws._conns_lock:
            self.rws._conns.discard(self.connection)

    def log_message(self, fmt, *args) -> None:
        log.debug("rws server: " + fmt, *args)

    # -- replies ----------------------------------------------------------------------------

    def _send(self, status: int, doc: dict | None = None,
              headers: list[tuple[str, str]] = ()) -> None:
        """The answer, with this request's session cookies (a new session's)."""
        body = json.dumps(doc).encode() if doc is not None else b""
        self.send_response(status)
        if doc is not None:
            self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        for k, v in [*headers, *self._cookies]:
            self.send_header(k, v)
        self.end_headers()
        if body:
            self.wfile.write(body)

    def _items(self, base: str, *items: dict) -> None:
        self._send(200, C.state_doc(f"http://{self.rws.host}:{self.rws.port}/{base}/",
                                    items))

    # -- the request ------------------------------------------------------------------------

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        self._handle("GET")

    def do_POST(self) -> None:  # noqa: N802
        self._handle("POST")

    def _session(self) -> str | None:
        cookie = SimpleCookie(self.headers.get("Cookie", ""))
        sid = cookie[SESSION_COOKIE].value if SESSION_COOKIE in cookie else None
        return sid if sid in self.rws.sessions else None

    def _handle(self, method: str) -> None:
        rws = self.rws
        length = int(self.headers.get("Content-Length") or 0)
        body = self.rfile.read(length).decode("utf-8", "replace") if length else ""
        f = rws.faults
        f.begin_command()
        if f.fires("drop"):
            self.close_connection = True
            with contextlib.suppress(OSError):
                self.connection.shutdown(socket.SHUT_RDWR)
            return
        if f.fires("slow") and rws._stop.wait(f.delay_s):
            return
        self._cookies: list[tuple[str, str]] = []
        sid = self._session()
        if sid is None:
            auth = self.headers.get("Authorization", "")
            if not (auth.lower().startswith("digest")
                    and rws.check_digest(method, self.path, auth)):
                self._send(401, C.error_doc(-1, "Unauthorized"), [(
                    "WWW-Authenticate", f'Digest realm="{C.REALM}", nonce="{rws.new_nonce()}", '
                                        'qop="auth", algorithm=MD5')])
                return
            sid = os.urandom(12).hex()
            rws.sessions.add(sid)
            self._cookies = [("Set-Cookie", f"{SESSION_COOKIE}={sid}; Path=/"),
                             ("Set-Cookie", f"{ABBCX}={os.urandom(6).hex()}; Path=/")]
        parts = urlsplit(self.path)
        path = unquote(parts.path).strip("/")
        query = {k: v[-1] for k, v in parse_qs(parts.query).items()}
        form = {k: v[-1] for k, v in parse_qs(body, keep_blank_values=True).items()}
        try:
            with rws.controller.lock:
                rws.controller.step()
                if method == "GET":
                    self._get(path, sid)
                else:
                    self._post(path, query.get("action", ""), form, sid)
        except RwsRefused as e:
            self._send(e.status, C.error_doc(e.code, e.msg))

    def _get(self, path: str, sid: str) -> None:
        rws, ctl, cell = self.rws, self.rws.controller, self.rws.cell
        prefix = f"rw/rapid/symbol/data/RAPID/{C.TASK}/"
        if path == C.CTRLSTATE:
            return self._items("rw/panel", {"_type": "pnl-ctrlstate", "_title": "ctrlstate",
                                            "ctrlstate": ctl.ctrlstate()})
        if path == C.OPMODE:
            return self._items("rw/panel", {"_type": "pnl-opmode", "_title": "opmode",
                                            "opmode": ctl.opmode})
        if path == C.SPEEDRATIO:
            return self._items("rw/panel", {"_type": "pnl-speedratio", "_title": "speedratio",
                                            "speedratio": str(ctl.speedratio)})
        if path == C.EXECUTION:
            return self._items("rw/rapid", {"_type": "rap-execution", "_title": "execution",
                                            "ctrlexecstate": ctl.execstate(),
                                            "cycle": "forever"})
        if path == C.TASKS:
            return self._items("rw/rapid", {
                "_type": "rap-task-li", "_title": C.TASK, "name": C.TASK, "type": "normal",
                "taskstate": "started", "excstate": "started" if ctl.running else "stopped",
                "active": "On", "motiontask": "TRUE"})
        if path.startswith(prefix):
            name = _symbol_name(path[len(prefix):])
            return self._items("rw/rapid/symbol/data", {
                "_type": "rap-data", "_title": f"RAPID/{C.TASK}/{C.MODULE}/{name}",
                "value": ctl.symbol(name)})
        if path == C.jointtarget_path(C.MECHUNIT):
            return self._items("rw/motionsystem", _jointtarget_items(cell.robot_state().q))
        if path == f"rw/motionsystem/mechunits/{C.MECHUNIT}/robtarget":
            tcp = cell.robot_state().tcp
            item = {"_type": "ms-robtargets", "_title": C.MECHUNIT,
                    **{k: f"{v:.6f}" for k, v in zip("xyz", tcp, strict=True)},
                    "q1": "1", "q2": "0", "q3": "0", "q4": "0",
                    "cf1": "0", "cf4": "0", "cf6": "0", "cfx": "0",
                    **{f"eax{c}": "9E+09" for c in "abcdef"}}
            return self._items("rw/motionsystem", item)
        if path == C.IDENTITY:
            return self._items("ctrl", {"_type": "ctrl-identity-info", "_title": "identity",
                                        "ctrl-name": CTRL_NAME, "ctrl-type": CTRL_TYPE,
                                        "ctrl-id": cell.serial("robot")})
        if path == C.SYSTEM:
            return self._items("rw/system", {
                "_type": "sys-system-li", "_title": "system", "name": RW_VERSION,
                "rwversion": RW_VERSION, "rwversionname": RW_VERSION_NAME,
                "sysid": "{cellcal-sim}", "starttm": "2024-01-01 T  00:00:00"})
        if path == C.ROBOTTYPE:
            return self._items("rw/system", {"_type": "sys-robottype", "_title": "1",
                                             "robot-type": cell.kinematics or "unknown"})
        if path in (C.MASTERSHIP, C.MASTERSHIP + "/rapid", C.MASTERSHIP + "/motion",
                    C.MASTERSHIP + "/cfg"):
            held = ctl.master is not None
            return self._items("rw/mastership", {
                "_type": "msh-resource", "_title": path.split("/")[-1],
                "mastership": "remote" if held else "nomaster",
                "mastershipheldbyme": "TRUE" if ctl.master == sid else "FALSE",
                "application": ctl.master or ""})
        if path.rstrip("/") == C.ELOG:
            items = [{"_type": "elog-message-li", "_title": f"/rw/elog/0/{e['seqnum']}",
                      "msgtype": str(e["msgtype"]), "code": str(e["code"]),
                      "tstamp": e["tstamp"], "title": e["title"], "desc": e["desc"],
                      "conseqs": "", "causes": "", "actions": "", "argc": "0"}
                     for e in reversed(ctl.elog)]
            return self._items("rw/elog/0", *items)
        if path == C.LOGOUT:
            ctl.release_mastership(sid)
            rws.sessions.discard(sid)
            return self._send(200, C.state_doc("", []))
        raise RwsRefused(404, "not_found", f"no resource /{path}")

    def _post(self, path: str, action: str, form: dict, sid: str) -> None:
        ctl = self.rws.controller
        prefix = f"rw/rapid/symbol/data/RAPID/{C.TASK}/"
        if path.startswith(prefix) and action == "set":
            if "value" not in form:
                raise RwsRefused(400, "bad_request", "a set needs value=")
            ctl.set_symbol(sid, _symbol_name(path[len(prefix):]), form["value"])
        elif path.startswith(C.MASTERSHIP) and action == "request":
            ctl.request_mastership(sid)
        elif path.startswith(C.MASTERSHIP) and action == "release":
            ctl.release_mastership(sid)
        elif path == C.EXECUTION and action == "start":
            ctl.start(sid)
        elif path == C.EXECUTION and action == "stop":
            ctl.stop(sid)
        elif path == C.EXECUTION and action == "resetpp":
            ctl.resetpp(sid)
        elif path == C.CTRLSTATE and action == "setctrlstate":
            ctl.set_ctrlstate(sid, form.get("ctrl-state", ""))
        elif path.startswith(f"{C.TASKS}/") and action in ("activate", "deactivate"):
            pass  # one motion task, always active
        else:
            raise RwsRefused(404, "not_found", f"no action {action!r} on /{path}")
        self._send(204)
