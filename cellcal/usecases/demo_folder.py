"""The guard on the demo's output folder: the demo writes only its own files, replaces
them only in a folder it made (its manifest, ``demo.json``, says so), and never deletes a
run store it did not create."""

from __future__ import annotations

import json
from pathlib import Path

#: the files the demo writes in its folder (with SQLite's side files of the store); it
#: writes no others and replaces these only in a folder it made (see check_demo_folder)
DEMO_FILES = ("cell.db", "cell.db-wal", "cell.db-shm", "cell.db-journal", "capture.csv",
              "params.json", "report.html", "demo.json")
#: marks demo.json as the demo's manifest
MANIFEST_KEY = "cellcal_demo"


class DemoFolderError(ValueError):
    """The demo's output folder holds files the demo did not write (exit 2)."""


def _manifest(folder: Path) -> dict | None:
    """The demo's manifest (demo.json) in ``folder``, or None when there is none."""
    try:
        doc = json.loads((folder / "demo.json").read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and isinstance(doc.get("files"), dict) else None


def check_demo_folder(out: Path, force: bool = False) -> None:
    """Refuse an output folder the demo would damage.

    A folder holding files the demo did not write (no demo manifest, or files besides
    :data:`DEMO_FILES`) is refused unless ``force``; even then a run store the demo did
    not create (``cell.db`` without the demo's manifest) is never deleted."""
    if out.exists() and not out.is_dir():
        raise DemoFolderError(f"--out {out}: a file, not a folder; give a new or empty folder")
    if not out.exists():
        return
    entries = sorted(p.name for p in out.iterdir())
    manifest = _manifest(out)
    foreign = [e for e in entries if manifest is None or e not in DEMO_FILES]
    if foreign and not force:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5
                                          else "")
        raise DemoFolderError(
            f"--out {out} holds files the demo did not write ({shown}); give a new or empty "
            "folder, or --force to write the demo's files (capture.csv, params.json, "
            "report.html, ...) there anyway")
    if manifest is None and (out / "cell.db").exists():
        raise DemoFolderError(
            f"--out {out}: cell.db there is a run store the demo did not create; the demo "
            "never deletes one, even with --force: give another folder")
