"""A throwaway PostgreSQL server for the tests and the benchmarks: initdb + pg_ctl in a
temporary directory, listening on a free loopback port, trust authentication.

The binaries come from ``$PG_BINDIR``, Debian's ``/usr/lib/postgresql/<version>/bin``
(the ``postgresql`` package) or ``PATH``. initdb refuses to run as root: as root the
server runs as the ``postgres`` user (created by Debian's package) through ``runuser``.

::

    with PgServer.start_new() as pg:
        url = pg.create_database("cell")      # postgresql://cellcal@127.0.0.1:PORT/cell
        pg.restart()                          # clients lose their connections
"""

from __future__ import annotations

import contextlib
import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

#: the superuser initdb creates (trust authentication on loopback only)
USER = "cellcal"
#: what to install when the binaries are missing (CI does it in .ci/run)
INSTALL_HINT = "apt-get update && apt-get install -y postgresql"


def find_bindir() -> Path | None:
    """The directory holding ``initdb``, ``pg_ctl`` and ``postgres``, or None."""
    candidates = []
    if os.environ.get("PG_BINDIR"):
        candidates.append(os.environ["PG_BINDIR"])
    debian = sorted(glob.glob("/usr/lib/postgresql/*/bin"),
                    key=lambda p: int(Path(p).parent.name) if Path(p).parent.name.isdigit()
                    else 0)
    candidates += reversed(debian)
    on_path = shutil.which("pg_ctl")
    if on_path:
        candidates.append(str(Path(on_path).resolve().parent))
    for c in candidates:
        d = Path(c)
        if all((d / exe).exists() for exe in ("initdb", "pg_ctl", "postgres")):
            return d
    return None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PgServer:
    """One PostgreSQL cluster in ``root`` (see the module docstring).

    Parameters
    ----------
    bindir : Path
    root : Path
        An empty directory (the data directory, the socket and the log go inside).
    fsync : bool
        The server's ``fsync`` (on: a commit is on disk when it returns, as in a plant).
    """

    def __init__(self, bindir: Path, root: Path, *, fsync: bool = True) -> None:
        self.bindir, self.root = Path(bindir), Path(root)
        self.data = self.root / "data"
        self.log = self.root / "server.log"
        self.port = _free_port()
        self.fsync = fsync
        self._as_user: list[str] = []
        if os.geteuid() == 0:
            try:
                pw = pwd.getpwnam("postgres")
            except KeyError:
                raise RuntimeError("running as root needs a 'postgres' user to run the "
                                   f"server as ({INSTALL_HINT} creates one)") from None
            os.chown(self.root, pw.pw_uid, pw.pw_gid)
            self._as_user = ["runuser", "-u", "postgres", "--"]
        self._run(["initdb", "-D", str(self.data), "-U", USER, "--auth=trust", "-E", "UTF8",
                   "--no-locale", "--no-sync"])
        with open(self.data / "postgresql.conf", "a") as fh:
            fh.write(f"\nlisten_addresses = '127.0.0.1'\nport = {self.port}\n"
                     f"unix_socket_directories = '{self.root}'\n"
                     f"fsync = {'on' if fsync else 'off'}\nmax_connections = 100\n"
                     "shared_buffers = 32MB\n")

    @classmethod
    @contextlib.contextmanager
    def start_new(cls, *, fsync: bool = True):
        """A started server in a new temporary directory; stopped and removed on exit.
        RuntimeError when the binaries are missing."""
        bindir = find_bindir()
        if bindir is None:
            raise RuntimeError(f"PostgreSQL server binaries not found ({INSTALL_HINT})")
        root = Path(tempfile.mkdtemp(prefix="cellcal-pg-"))
        try:
            server = cls(bindir, root, fsync=fsync)
            server.start()
            try:
                yield server
            finally:
                server.stop()
        finally:
            shutil.rmtree(root, ignore_errors=True)

    def _run(self, argv: list[str]) -> None:
        cmd = [*self._as_user, str(self.bindir / argv[0]), *argv[1:]]
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=120,
                             stdin=subprocess.DEVNULL)
        if out.returncode != 0:
            log = self.log.read_text() if self.log.exists() else ""
            raise RuntimeError(f"{' '.join(argv[:2])} failed ({out.returncode}): "
                               f"{out.stderr.strip()}\n{log[-2000:]}")

    # ----------------------------------------------------------- lifecycle
    def start(self) -> None:
        self._run(["pg_ctl", "-D", str(self.data), "-l", str(self.log), "-w", "-t", "60",
                   "start"])

    def stop(self, mode: str = "fast") -> None:
        """Stop the server (``fast``: clients are disconnected; ``immediate``: a crash)."""
        self._run(["pg_ctl", "-D", str(self.data), "-m", mode, "-w", "-t", "60", "stop"])

    def restart(self, mode: str = "fast") -> None:
        self.stop(mode)
        self.start()

    def running(self) -> bool:
        try:
            with socket.create_connection(("127.0.0.1", self.port), timeout=0.5):
                return True
        except OSError:
            return False

    # ------------------------------------------------------------ databases
    def url(self, dbname: str = "postgres") -> str:
        return f"postgresql://{USER}@127.0.0.1:{self.port}/{dbname}"

    def admin(self, sql: str) -> None:
        """Run one statement (outside a transaction) in the ``postgres`` database."""
        import psycopg

        deadline = time.monotonic() + 30
        while True:
            try:
                with psycopg.connect(self.url(), autocommit=True, connect_timeout=5) as con:
                    con.execute(sql)
                return
            except psycopg.OperationalError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)

    def create_database(self, name: str) -> str:
        """A new, empty database; its URL."""
        self.admin(f'CREATE DATABASE "{name}"')
        return self.url(name)

    def drop_database(self, name: str) -> None:
        self.admin(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
