"""One owner per run and per robot: leases in the run store.

A capture or a resume holds a lease on its run (``run:ID``) and on its robot
(:func:`robot_key`: the normalised robot URL, and ``robot-id:MODEL/SERIAL`` once the
controller has said who it is) for as long as it may move the robot. A lease names its
owner (pid, host, a random token) and carries a heartbeat that a background thread
renews every ``ttl_s / 3`` seconds. A second process asking for a held lease is refused
at once (:class:`LeaseBusy`, exit code 2 at the command line, naming the owner); a
stale lease — its owner's pid gone on this host, or its heartbeat older than ``ttl_s``
(an owner on another host, a frozen process) — is taken over, and :meth:`Leases.acquire`
returns the stale owner so the caller can say so.

The ``leases`` table (store schema 5, :mod:`daq.store.schema`) lives in the run store,
a SQLite file or a PostgreSQL database alike; this module uses its own connection
(:func:`daq.store.dialect.connect`; the heartbeat thread shares it under a lock), so it
works beside an open :class:`~daq.store.RunStore`. Its SQL is the store's spelling: the
take-over is one transaction under the store's write lock (``BEGIN IMMEDIATE`` on
SQLite, an advisory lock on PostgreSQL) and the new owner is an upsert.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast
from urllib.parse import parse_qsl, urlencode, urlsplit

from ..errors import RequestError
from .dialect import connect
from .errors import StoreError

if TYPE_CHECKING:
    from drivers.protocols import DeviceIdentity

    from .runstore import RunStore

#: what a best-effort write (release, heartbeat, close) may meet and shrug off (the
#: store's databases raise nothing else: :mod:`daq.store.dialect`)
_DB_ERRORS = (StoreError,)

#: seconds without a heartbeat after which a lease counts as abandoned
DEFAULT_TTL_S = 30.0

#: default ports of the network robot schemes (a URL without a port means these)
_DEFAULT_PORTS = {"modbus+tcp": 502, "ur": 30004}
#: sim:// query parameters that do not change which simulated robot it is
_SIM_IGNORED = {"time_scale", "faults"}


def run_key(run_id: int) -> str:
    """The lease key of a run."""
    return f"run:{int(run_id)}"


def robot_key(url: str) -> str:
    """The lease key of the robot behind ``url``: scheme, host (``localhost`` as
    127.0.0.1) and port (the scheme's default when absent), a device path resolved
    through symlinks; ``sim://`` keeps the query parameters that name the cell."""
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme == "serial":
        return f"robot:serial://{os.path.realpath(parts.path)}"
    if scheme == "sim":
        q = sorted((k, v) for k, v in parse_qsl(parts.query) if k not in _SIM_IGNORED)
        return f"robot:sim://{parts.netloc or parts.path.strip('/')}?{urlencode(q)}"
    host = (parts.hostname or "").lower()
    if host == "localhost":
        host = "127.0.0.1"
    try:
        port = parts.port or _DEFAULT_PORTS.get(scheme)
    except ValueError:
        port = None
    return f"robot:{scheme}://{host}" + (f":{port}" if port else "")


def robot_identity_key(model: str, serial: str) -> str | None:
    """The lease key of a robot by what it says it is; None without a serial number."""
    return f"robot-id:{model}/{serial}" if serial else None


@dataclass(frozen=True)
class LeaseOwner:
    """Who holds a lease: process, host, its token, since when and its last heartbeat."""

    key: str
    pid: int
    host: str
    token: str
    acquired: float
    heartbeat: float
    what: str = ""

    def describe(self, now: float | None = None) -> str:
        now = time.time() if now is None else now
        return (f"pid {self.pid} on {self.host} ({self.what or self.key}, heartbeat "
                f"{max(now - self.heartbeat, 0.0):.1f} s ago)")


class LeaseBusy(RequestError):
    """The lease is held by a live owner: ``owner`` (:class:`LeaseOwner`)."""

    def __init__(self, owner: LeaseOwner, message: str) -> None:
        self.owner = owner
        super().__init__(message)


def _alive(owner: LeaseOwner, host: str, ttl_s: float, now: float) -> bool:
    if now - owner.heartbeat > ttl_s:
        return False
    if owner.host != host:
        return True
    try:
        os.kill(owner.pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


class Leases:
    """This process's leases in the run store ``path``; a context manager that releases
    them all (and stops the heartbeat) on exit.

    Parameters
    ----------
    path : str, Path or RunStore
        The run store (schema 5 or later: the ``leases`` table): a SQLite file, a
        ``postgresql://`` URL, or an open :class:`~daq.store.RunStore` (whose address it
        connects to again: a URL's password is not in ``RunStore.path``).
    ttl_s : float
        A heartbeat older than this makes a lease stale.
    """

    def __init__(self, path: str | Path | RunStore, *, ttl_s: float = DEFAULT_TTL_S) -> None:
        new_connection = getattr(path, "new_connection", None)
        self.path: str | Path = (cast("RunStore", path).path if new_connection is not None
                                 else cast("str | Path", path))
        self.ttl_s = float(ttl_s)
        self.host = socket.gethostname()
        self.pid = os.getpid()
        self.token = secrets.token_hex(8)
        self._con = new_connection() if new_connection is not None else connect(
            self.path, create=False)
        self._lock = threading.Lock()
        self._held: dict[str, str] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------- acquire
    def _owner(self, key: str) -> LeaseOwner | None:
        r = self._con.execute("SELECT key, owner_pid, owner_host, owner_token, acquired, "
                              "heartbeat, what FROM leases WHERE key=?", (key,)).fetchone()
        return None if r is None else LeaseOwner(*r)

    def acquire(self, key: str, what: str = "") -> LeaseOwner | None:
        """Hold ``key`` (``what`` says what for, in messages to others).

        Returns the stale owner taken over, or None. Raises :class:`LeaseBusy` naming
        the owner when a live one holds it. Holding it already is a no-op.
        """
        with self._lock:
            if key in self._held:
                return None
            now = time.time()
            with self._con.transaction(lock=True):  # LeaseBusy rolls it back
                old = self._owner(key)
                if old is not None and old.token != self.token and _alive(
                        old, self.host, self.ttl_s, now):
                    raise LeaseBusy(old, f"{what or key} is in use by {old.describe(now)}: "
                                         "wait for it to finish or stop it, then try again")
                self._con.upsert("leases", ["key"], {
                    "key": key, "owner_pid": self.pid, "owner_host": self.host,
                    "owner_token": self.token, "acquired": now, "heartbeat": now,
                    "what": what})
            self._held[key] = what
        self._start_heartbeat()
        return old if old is not None and old.token != self.token else None

    def holds(self, key: str) -> bool:
        return key in self._held

    def release(self, key: str) -> None:
        """Give ``key`` up (only if this object holds it)."""
        with self._lock:
            if self._held.pop(key, None) is None:
                return
            with contextlib.suppress(*_DB_ERRORS):
                self._con.execute("DELETE FROM leases WHERE key=? AND owner_token=?",
                                  (key, self.token))

    # ----------------------------------------------------------- heartbeat
    def beat(self) -> None:
        """Renew the heartbeat of every lease held (the thread does it every ttl/3)."""
        with self._lock:
            if not self._held:
                return
            keys = list(self._held)
            with contextlib.suppress(*_DB_ERRORS):
                self._con.executemany("UPDATE leases SET heartbeat=? WHERE key=? AND "
                                      "owner_token=?",
                                      [(time.time(), k, self.token) for k in keys])

    def _start_heartbeat(self) -> None:
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name="cellcal-lease", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.ttl_s / 3.0):
            self.beat()

    # ------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Release every lease held and stop the heartbeat (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        for key in list(self._held):
            self.release(key)
        with contextlib.suppress(*_DB_ERRORS):
            self._con.close()

    def __enter__(self) -> Leases:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextlib.contextmanager
def held_leases(path: str | Path, given: Leases | None) -> Iterator[Leases]:
    """The caller's ``given`` leases (kept when the block ends), else new ones for the
    store ``path`` (released when it ends)."""
    if given is not None:
        yield given
        return
    with Leases(path) as own:
        yield own


def take_robot(leases: Leases, url: str, identity: DeviceIdentity | None = None) -> None:
    """Hold the robot at ``url``, and by its serial number once ``identity`` (a
    :class:`drivers.protocols.DeviceIdentity`) gives one: the same robot reached by
    another URL is the same robot."""
    leases.acquire(robot_key(url), f"robot {url}")
    if identity is not None:
        key = robot_identity_key(identity.model, identity.serial)
        if key is not None:
            leases.acquire(key, f"robot {identity}")
