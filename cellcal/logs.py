"""The command line's logging: set up once per command from its flags, and the log a
capture keeps beside its run (docs/logging.md).

The libraries (``calibration``, ``drivers``, ``daq``, ``sim_drivers``, ``presentation``)
log to ``logging.getLogger(__name__)`` and configure nothing; the application does, here:

* :func:`configured` (around a command, from :func:`cellcal.cli.main`): records of the
  project's loggers at the level the flags choose (:func:`~cellcal.flags.log_flags.
  chosen_level`, default WARNING) go to stderr, one line each
  (``2025-05-01 10:00:00,123 INFO daq.executor: point 3 (p003): joint move to ...``);
  with ``--log-file`` they go to that file (appended to, flushed per record) and stderr
  shows warnings only. Other libraries' loggers keep the root's WARNING; pymodbus, whose
  failures the Modbus driver turns into its errors, is heard only at DEBUG. Everything
  is undone at the end (a command run in-process leaves no handler behind).
* :class:`RunLog` (around ``capture``, ``resume``, ``validate``): from the moment the
  command starts, the capture service's records at INFO (DEBUG with ``-vv`` or
  ``--log-level DEBUG``) are kept; once the run is stored and has its id
  (:meth:`RunLog.open`) they are written to the run's log file (:func:`run_log_path`),
  and every later record too, flushed one by one, so an interrupted capture loses
  nothing written before. A resumed run appends to the same file.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import re
import stat
import sys
from pathlib import Path

from .errors import UsageError
from .flags.log_flags import chosen_level

log = logging.getLogger(__name__)

#: one line per record
FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
#: the start of a line this format writes (what makes an existing file a cellcal log)
RECORD_START = re.compile(rb"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} "
                          rb"(DEBUG|INFO|WARNING|ERROR|CRITICAL) \S+: ")
#: the project's packages: their loggers get the chosen level
PACKAGES = ("calibration", "cellcal", "daq", "drivers", "presentation", "sim_drivers")
#: records kept before a run's log file is known (the oldest dropped beyond)
BUFFERED = 10000


class OneLineFormatter(logging.Formatter):
    """:data:`FORMAT`, a record's lines (a message's, a traceback's) joined by `` | ``."""

    def __init__(self) -> None:
        super().__init__(FORMAT)

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        return " | ".join(line for line in text.splitlines() if line.strip())


def check_log_file(path: str | Path, what: str = "--log-file") -> Path:
    """``path`` if a log may be appended to it: a new file in an existing folder, an empty
    file or a cellcal log (its first line one of :data:`FORMAT`'s), or a character device
    (``/dev/stderr``); a UsageError naming ``what`` otherwise (an input is never written)."""
    p = Path(path)
    if str(path) == "":
        raise UsageError(f"{what}: an empty path")
    try:
        st = p.stat()
    except FileNotFoundError:
        if not p.parent.is_dir():
            raise UsageError(f"{what} {path}: no such folder {str(p.parent)!r}") from None
        return p
    except OSError as e:
        raise UsageError(f"{what} {path}: {e.strerror or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise UsageError(f"{what} {path}: is a directory, not a log file")
    if stat.S_ISCHR(st.st_mode):
        return p
    if not stat.S_ISREG(st.st_mode):
        raise UsageError(f"{what} {path}: not a regular file")
    if st.st_size == 0:
        return p
    try:
        with open(p, "rb") as f:
            head = f.read(4096)
    except OSError as e:
        raise UsageError(f"{what} {path}: {e.strerror or e}") from None
    if not RECORD_START.match(head):
        raise UsageError(f"{what} {path}: exists and is not a cellcal log (a log is appended "
                         "to, never overwritten): name a new file")
    return p


class _Stderr(logging.StreamHandler):
    """stderr; each record first erases the progress line a capture keeps refreshed in
    place on a terminal (:func:`cellcal.progress.erase_line`: drawn again at its next
    update)."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    def emit(self, record: logging.LogRecord) -> None:
        from .progress import erase_line

        erase_line()
        super().emit(record)


def _file_handler(path: Path) -> logging.Handler:
    h = logging.FileHandler(path, mode="a", encoding="utf-8")  # flushed after each record
    h.setFormatter(OneLineFormatter())
    return h


class _Levels:
    """Loggers' levels set for a while and put back as they were."""

    def __init__(self) -> None:
        self._saved: list[tuple[logging.Logger, int]] = []

    def set(self, name: str, level: int) -> None:
        lg = logging.getLogger(name)
        self._saved.append((lg, lg.level))
        lg.setLevel(level)

    def lower(self, names, level: int) -> None:
        """``names``' loggers at ``level`` at least (a lower level kept)."""
        for name in names:
            lg = logging.getLogger(name)
            if lg.level == logging.NOTSET or lg.level > level:
                self.set(name, level)

    def restore(self) -> None:
        for lg, level in reversed(self._saved):
            lg.setLevel(level)
        self._saved.clear()


@contextlib.contextmanager
def configured(args):
    """Logging set up for one command from its flags (module docstring), undone after.

    Raises UsageError for a ``--log-file`` that must not be written (:func:`check_log_file`).
    """
    level = logging.getLevelName(chosen_level(args))
    path = getattr(args, "log_file", None)
    target = None if path is None else check_log_file(path)
    root = logging.getLogger()
    handlers: list[logging.Handler] = []
    levels = _Levels()
    try:
        stderr = _Stderr()
        stderr.setFormatter(OneLineFormatter())
        stderr.setLevel(level if target is None else max(level, logging.WARNING))
        handlers.append(stderr)
        if target is not None:
            handlers.append(_file_handler(target))
            handlers[-1].setLevel(level)
        for h in handlers:
            root.addHandler(h)
        levels.lower(PACKAGES, level)
        # pymodbus reports every failure the Modbus driver turns into its errors
        levels.set("pymodbus", logging.WARNING if level <= logging.DEBUG
                   else logging.CRITICAL + 1)
        yield level
    finally:
        levels.restore()
        for h in handlers:
            root.removeHandler(h)
            h.close()


class _Buffer(logging.Handler):
    """Keeps records (at most :data:`BUFFERED`) until they can be written."""

    def __init__(self, level: int) -> None:
        super().__init__(level)
        self.records: collections.deque[logging.LogRecord] = collections.deque(
            maxlen=BUFFERED)

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


#: the folder of the logs of a PostgreSQL store's runs (default: the current directory)
RUN_LOG_DIR_ENV = "CELLCAL_RUN_LOG_DIR"


def run_log_path(db, run_id: int) -> Path:
    """The log file of run ``run_id`` of the run store ``db``: ``<db>.run<ID>.log`` beside a
    SQLite file; for a PostgreSQL store (no folder of its own),
    ``postgresql-<host>-<dbname>.run<ID>.log`` in ``$CELLCAL_RUN_LOG_DIR``, else in the
    current directory."""
    import os
    from urllib.parse import urlsplit

    from daq.store.addresses import is_server_address

    if not is_server_address(str(db)):
        return Path(f"{db}.run{run_id}.log")
    parts = urlsplit(str(db))
    name = f"postgresql-{parts.hostname or 'localhost'}-{parts.path.strip('/') or 'postgres'}"
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", name) + f".run{run_id}.log"
    return Path(os.environ.get(RUN_LOG_DIR_ENV) or ".") / name


class RunLog:
    """The log a capture keeps beside its run (module docstring); a context manager around
    the command's work, :meth:`open` once the run's id is known. ``path`` is the file
    written (None before, or when it could not be)."""

    def __init__(self, args) -> None:
        chosen = logging.getLevelName(chosen_level(args))
        self.level = min(chosen, logging.INFO)
        self.command_line = getattr(args, "command_line", None)
        self.path: Path | None = None
        self._buffer: _Buffer | None = None
        self._file: logging.Handler | None = None
        self._levels = _Levels()

    def __enter__(self) -> RunLog:
        self._levels.lower(PACKAGES, self.level)
        self._buffer = _Buffer(self.level)
        logging.getLogger().addHandler(self._buffer)
        if self.command_line:  # into the run's log only (stderr had it at the start)
            self._buffer.handle(log.makeRecord(log.name, logging.INFO, __file__, 0, "%s",
                                               (self.command_line,), None))
        return self

    def open(self, db, run_id: int) -> Path | None:
        """Write the run's log from now on (the records kept so far first); its path, or
        None when the file cannot be written (a warning says why; the capture goes on)."""
        root = logging.getLogger()
        if self._file is not None:
            root.removeHandler(self._file)
            self._file.close()
            self._file = None
        path = run_log_path(db, run_id)
        try:
            check_log_file(path, f"the log of run {run_id}")
            handler = _file_handler(path)
        except (UsageError, OSError) as e:
            log.warning("run %d: no log beside the run: %s", run_id, e)
            self.path = None
            return None
        handler.setLevel(self.level)
        for record in self._buffer.records if self._buffer is not None else ():
            if record.levelno >= self.level:
                handler.handle(record)
        if self._buffer is not None:
            self._buffer.records.clear()
        root.addHandler(handler)
        self._file, self.path = handler, path
        log.info("run %d: this log is %s", run_id, path)
        return path

    def __exit__(self, kind, exc, tb) -> None:
        root = logging.getLogger()
        if exc is not None and self._file is not None:
            log.info("ended by %s: %s", kind.__name__, exc)
            log.debug("the traceback", exc_info=(kind, exc, tb))
        if self._buffer is not None:
            root.removeHandler(self._buffer)
            self._buffer = None
        if self._file is not None:
            root.removeHandler(self._file)
            self._file.close()
            self._file = None
        self._levels.restore()
