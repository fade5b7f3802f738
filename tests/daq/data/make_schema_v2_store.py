"""Build ``schema_v2/cell.db``: a run store written by cellcal at schema version 2.

Run with the code of commit 5ca46ae (the last one writing schema v2) on the path, e.g.::

    mkdir /tmp/base && git archive 5ca46ae | tar -x -C /tmp/base
    PYTHONPATH=/tmp/base python tests/daq/data/make_schema_v2_store.py tests/daq/data/schema_v2

Against the simulated UR10e served on loopback it captures, through that version's own
command line: a frame run (1), a steps run with non-default executor options (2), a
zero20 run with the closed-loop options set (3, it copies the frame run's
``tracker_T_base``/``tracker_R_base`` into its options), and a poses run paused by a
protective stop (4, resumable). It then writes what that version exports: ``runN.csv``
(``cellcal export N``), ``postures3.csv`` (``cellcal export 3 --postures``) and
``runs.json`` (``cellcal runs --json``). ``tests/daq/test_store_upgrade.py`` checks that
the current code upgrades the store and exports the same.
"""

from __future__ import annotations

import contextlib
import io
import sqlite3
import sys
import threading
import time
from pathlib import Path

from cellcal.cli import main
from sim_drivers.model_truth import model_truth_factory
from sim_drivers.serve import ServeConfig, SimStack


def _cli(*argv: str) -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(list(argv))
    if rc not in (0, 1):
        raise SystemExit(f"{argv}: exit {rc}")
    return buf.getvalue()


def _count(db: Path, run: int) -> int:
    con = sqlite3.connect(db, timeout=5)
    try:
        return int(con.execute("SELECT count(*) FROM samples WHERE run_id=?",
                               (run,)).fetchone()[0])
    finally:
        con.close()


def build(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    db = out / "cell.db"
    for f in out.glob("cell.db*"):
        f.unlink()
    cfg = ServeConfig(seed=5, ports={"modbus": 0, "line_robot": 0, "tracker": 0}, pty=False)
    with SimStack(cfg, truth_factory=model_truth_factory) as stack:
        common = ["--model", "ur10e", "--tool-mm", "0,0,60", "--no-floor", "--robot",
                  stack.urls[1], "--tracker", stack.urls[2], "--db", str(db), "--json",
                  "--measure-s", "0.05"]
        start = ["--start-deg", "20,-100,100,-90,-90,0"]
        _cli("capture", "frame", *common, *start, "--circle-points", "4", "--line-points", "3",
             "--line-length-mm", "200")
        _cli("capture", "steps", *common, *start, "--count", "2", "--axes", "x", "--speed",
             "0.4", "--dwell", "0.01", "--seed", "7")
        _cli("capture", "zero20", *common, "--target-xyz", "700,150,250", "--zero-average",
             "2", "--zero-tol-mm", "0.02")

        def stop_after_two_points() -> None:
            while True:
                with contextlib.suppress(sqlite3.Error):
                    if _count(db, 4) >= 2:
                        stack.cell.faults.arm("pstop")
                        return
                time.sleep(0.001)

        watcher = threading.Thread(target=stop_after_two_points, daemon=True)
        watcher.start()
        _cli("capture", "poses", *common, "--count", "6", "--seed", "3")
        watcher.join(timeout=10)
    for run in (1, 2, 3, 4):
        _cli("export", str(run), "--db", str(db), "--out", str(out / f"run{run}.csv"))
    _cli("export", "3", "--postures", "--db", str(db), "--out", str(out / "postures3.csv"))
    (out / "runs.json").write_text(_cli("runs", "--db", str(db), "--json"))
    con = sqlite3.connect(db)
    con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    con.execute("PRAGMA journal_mode=DELETE")  # a small file: small pages (content unchanged)
    con.execute("PRAGMA page_size=1024")
    con.execute("VACUUM")
    con.execute("PRAGMA journal_mode=WAL")
    con.close()
    for f in out.glob("cell.db-*"):
        f.unlink()


if __name__ == "__main__":
    build(Path(sys.argv[1]))
