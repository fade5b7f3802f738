"""The guard on a command's outputs: :func:`check_outputs` refuses an output path that would
destroy something (an input, a run store, a directory, a path in a missing folder, one
file named twice); :func:`existing_paths` picks the inputs that are files.

Imports nothing heavy at load (the parser's modules import it: start-up stays fast).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from ..errors import UsageError


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_outputs(outputs: dict[str, str | None], inputs=(), *, stdout: bool = False) -> None:
    """Refuse output paths that would destroy something (UsageError, exit 2).

    ``outputs`` maps a flag (``--out``) to its path (None: not given); ``inputs`` are the
    command's input paths (None and non-paths such as built-in model names are skipped).
    Refused: an output that is an input, any SQLite file (a run store is never
    overwritten), a directory, a path in a missing folder, a folder not writable, and one
    path given for two outputs. ``stdout``: ``-`` means standard output.
    """
    from calibration.files import is_sqlite_file

    seen: dict[str, str] = {}
    ins = [Path(i) for i in inputs if i]
    for flag, out in outputs.items():
        if out is None or (stdout and out == "-"):
            continue
        p = Path(out)
        if p.is_dir():
            raise UsageError(f"{flag} {out}: is a directory; give a file name")
        folder = p.parent
        if not folder.is_dir():
            raise UsageError(f"{flag} {out}: the folder {folder} does not exist (no such "
                             "directory)")
        for i in ins:
            if _same_file(p, i) or p.resolve() == i.resolve():
                raise UsageError(f"{flag} {out} is an input of this command; write to a new "
                                 "file (cellcal never overwrites its inputs)")
        if is_sqlite_file(p):
            raise UsageError(f"{flag} {out}: is a run store (an SQLite database); cellcal "
                             "never overwrites one: give a new file name")
        if p.exists() and not p.is_file():
            continue  # /dev/null, /dev/stdout, a FIFO: written directly
        if not os.access(folder, os.W_OK):
            raise UsageError(f"{flag} {out}: the folder {folder} is not writable")
        key = str(p.resolve())
        if key in seen:
            raise UsageError(f"{seen[key]} and {flag} name the same file {out}; give two "
                             "different files")
        seen[key] = flag


def existing_paths(*values: str | Iterable[str] | None) -> list[str]:
    """The values that name existing files (sequences flattened; None and a built-in
    model name, which is no path, are skipped)."""
    out = []
    for v in values:
        for item in v if isinstance(v, (list, tuple)) else [v]:
            if item and isinstance(item, str) and Path(item).exists():
                out.append(item)
    return out
