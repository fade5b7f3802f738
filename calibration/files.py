"""Reading and writing the user's files safely: the one place both happen.

Writing (:func:`write_atomic`, :func:`atomic_output`)
    Every file cellcal writes goes to a temporary file in the same folder, is flushed to
    disk and renamed over the destination: an interrupted write (a full disk, a killed
    process) leaves the old file whole, never a half-written one. A destination that is
    not a regular file (``/dev/null``, ``/dev/stdout``, a FIFO) is written directly;
    a symbolic link is followed (its target is replaced, the link kept).

Reading (:func:`read_input`)
    An input must be a regular file (not a directory, a device such as ``/dev/zero`` or a
    FIFO that would block), within a size limit, and text must be UTF-8 (a byte-order
    mark is accepted); the error names the file and what is wrong, in one line, as the
    caller's exception type (``DataError``, ``ModelError``...).
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

#: the first bytes of every SQLite database file
SQLITE_MAGIC = b"SQLite format 3\x00"


# ------------------------------------------------------------------------- writing
@contextlib.contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """A temporary path to write instead of ``path``; renamed over it when the block ends
    without an exception (else removed). The temporary name keeps ``path``'s suffix (for
    writers that choose the format by it, e.g. matplotlib)."""
    dest = Path(path)
    if dest.is_symlink():
        dest = Path(os.path.realpath(dest))
    if dest.exists() and not dest.is_file():
        if dest.is_dir():
            raise IsADirectoryError(21, "Is a directory", str(path))
        yield dest  # a device or a FIFO: there is nothing to replace
        return
    folder = dest.parent
    fd, tmp_name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=f".tmp{dest.suffix}",
                                    dir=folder)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        _fsync(tmp)
        os.chmod(tmp, _mode_for(dest))
        os.replace(tmp, dest)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    _fsync_dir(folder)


def write_atomic(path: str | Path, data: str | bytes, encoding: str = "utf-8") -> Path:
    """Write ``data`` (text is encoded as UTF-8) to ``path`` atomically; returns the path."""
    raw = data.encode(encoding) if isinstance(data, str) else data
    with atomic_output(path) as tmp, open(tmp, "wb") as f:
        f.write(raw)
    return Path(path)


def _mode_for(dest: Path) -> int:
    """The permission bits of the file being replaced, else those a new file gets."""
    try:
        return stat.S_IMODE(dest.stat().st_mode)
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _fsync(path: Path) -> None:
    with contextlib.suppress(OSError), open(path, "rb+") as f:
        os.fsync(f.fileno())


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


# ------------------------------------------------------------------------- reading
def check_regular_file(path: str | Path, error: type[Exception], what: str = "file") -> Path:
    """``path`` as a Path when it is an existing regular file, else ``error`` saying why."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        folder = p.parent
        if str(folder) not in ("", ".") and not folder.is_dir():
            raise error(f"{path}: no such file (the folder {folder} does not exist)") from None
        raise error(f"{path}: no such file") from None
    except OSError as e:
        raise error(f"{path}: cannot read the {what}: {e.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{path}: is a directory, not a {what}") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a FIFO (pipe)" if stat.S_ISFIFO(st.st_mode) else "a device or special file"
        raise error(f"{path}: not a regular file ({kind}); give a {what}")
    return p


def read_input(path: str | Path, error: type[Exception], what: str = "file",
               max_bytes: int = 200 << 20) -> bytes:
    """The bytes of an input file; ``error`` (one line naming the file) when it is missing,
    not a regular file, unreadable or larger than ``max_bytes``."""
    p = check_regular_file(path, error, what)
    size = p.stat().st_size
    if size > max_bytes:
        raise error(f"{path}: {size / 1e6:.0f} MB is too large for a {what} "
                    f"(limit {max_bytes / 1e6:.0f} MB)")
    try:
        return p.read_bytes()
    except OSError as e:
        raise error(f"{path}: cannot read the {what}: {e.strerror}") from None


def decode_text(raw: bytes, source: str, error: type[Exception], what: str = "file") -> str:
    """UTF-8 text of a file (a leading byte-order mark dropped); ``error`` for binary data,
    UTF-16 or another encoding, naming the line of the first bad byte."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise error(f"{source}: UTF-16 text; save the {what} as UTF-8")
    if raw.startswith(b"\xef\xbb\xbf"):  # a byte-order mark: dropped (and not counted)
        raw = raw[3:]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        if b"\x00" in raw[:4096]:
            raise error(f"{source}: a binary file, not a {what} (UTF-8 text expected)") from None
        raise error(f"{source}: line {line}: byte 0x{raw[e.start]:02x} is not UTF-8; save the "
                    f"{what} as UTF-8") from None
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise error(f"{source}: line {line}: a NUL byte: a binary file, not a {what}")
    return text


def read_text(path: str | Path, error: type[Exception], what: str = "file",
              max_bytes: int = 200 << 20) -> str:
    """:func:`read_input` then :func:`decode_text`."""
    return decode_text(read_input(path, error, what, max_bytes), str(path), error, what)


class TextLines:
    """The lines of a UTF-8 text file, ``(line number, line)`` as
    ``enumerate(read_text(...).splitlines(), 1)`` gives them, read a block at a time: a
    large file is never held whole.

    The file is checked as :func:`read_input` and :func:`decode_text` check it, and the
    same error comes first: a byte that is not UTF-8 anywhere in the file before a NUL
    byte anywhere. A caller that stops at an error of its own (a bad row) calls
    :meth:`check_rest`, which raises the file's encoding error instead when there is one.
    """

    #: bytes read at a time
    BLOCK = 1 << 20

    def __init__(self, path: str | Path, error: type[Exception], what: str = "file",
                 max_bytes: int = 200 << 20) -> None:
        p = check_regular_file(path, error, what)
        size = p.stat().st_size
        if size > max_bytes:
            raise error(f"{path}: {size / 1e6:.0f} MB is too large for a {what} "
                        f"(limit {max_bytes / 1e6:.0f} MB)")
        self.path, self.source, self.error, self.what = p, str(path), error, what
        self._file: BinaryIO | None = None
        self._rest = b""  # the bytes after the last line feed read
        self._head = b""  # the file's first bytes (what decode_text looks at)
        self._newlines = 0  # line feeds in the pieces decoded so far
        self._nul_line: int | None = None  # the line of the first NUL byte seen
        self._first = True  # the next piece is the file's first (a byte-order mark)
        self._done = False  # read to the end (or failed)
        self._bad: str | None = None  # the encoding error found

    def __iter__(self) -> Iterator[tuple[int, str]]:
        line_no = 0
        for text in self._pieces():
            if self._nul_line is not None:
                self.check_rest()
            for line in text.splitlines():
                line_no += 1
                yield line_no, line

    def check_rest(self) -> None:
        """Read the rest of the file: its encoding error, if any, else the NUL byte's."""
        for _ in self._pieces():
            pass
        if self._bad is not None:  # said already, and said again here
            raise self.error(self._bad)
        if self._nul_line is not None:
            raise self.error(f"{self.source}: line {self._nul_line}: a NUL byte: a binary "
                             f"file, not a {self.what}")

    def _pieces(self) -> Iterator[str]:
        """The file's text, decoded a piece at a time, each piece ending with a line feed
        (but the last): a line break (``\r\n`` too) never spans two pieces. Resumes where
        the last call stopped."""
        try:
            if self._file is None and not self._done:
                f = open(self.path, "rb")  # noqa: SIM115 - closed at the end below
                self._file = f
                self._head = self._rest = f.read(4096)
                if self._head.startswith((b"\xff\xfe", b"\xfe\xff")):
                    raise self.error(f"{self.source}: UTF-16 text; save the {self.what} "
                                     "as UTF-8")
            while self._file is not None:
                block = self._file.read(self.BLOCK)
                data = self._rest + block
                cut = data.rfind(b"\n") + 1 if block else len(data)
                piece, self._rest = data[:cut], data[cut:]
                if not block:
                    self._close()
                if piece:
                    first = self._first
                    self._first = False
                    yield self._decode(piece, first)
        except Exception:  # not GeneratorExit: a caller that stops may call check_rest
            self._close()
            raise

    def _decode(self, piece: bytes, first: bool) -> str:
        if first and piece.startswith(b"\xef\xbb\xbf"):  # a byte-order mark: dropped
            piece = piece[3:]
        try:
            text = piece.decode("utf-8")
        except UnicodeDecodeError as e:
            line = self._newlines + piece[: e.start].count(b"\n") + 1
            if b"\x00" in self._head:
                self._bad = (f"{self.source}: a binary file, not a {self.what} (UTF-8 text "
                             "expected)")
            else:
                self._bad = (f"{self.source}: line {line}: byte 0x{piece[e.start]:02x} is not "
                             f"UTF-8; save the {self.what} as UTF-8")
            raise self.error(self._bad) from None
        if self._nul_line is None and "\x00" in text:
            self._nul_line = self._newlines + text[: text.index("\x00")].count("\n") + 1
        self._newlines += piece.count(b"\n")
        return text

    def _close(self) -> None:
        self._done = True
        if self._file is not None:
            self._file.close()
            self._file = None


def sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def json_ready(o: Any) -> Any:
    """``o`` with every NaN and infinity (in nested dicts, lists and tuples) as None: what
    strict JSON can hold."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: json_ready(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [json_ready(v) for v in o]
    return o


def is_sqlite_file(path: str | Path) -> bool:
    """True when ``path`` is a regular file starting with SQLite's header."""
    try:
        p = Path(path)
        if not p.is_file():
            return False
        with open(p, "rb") as f:
            return f.read(16) == SQLITE_MAGIC
    except OSError:
        return False
