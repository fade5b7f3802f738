"""A plant's run store on a PostgreSQL server, end to end over real sockets: the server
restarted or gone during a capture (the run waits, or pauses and resumes, losing
nothing), and two cells capturing into one database at once."""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from daq.store import RunStore

from .capture_helpers import ROOT, count_samples, read_lines, sim_serve

CLI = [sys.executable, "-m", "cellcal"]
POINTS = 120


@pytest.fixture(scope="module")
def own_pg():
    """A server of these tests' own (they stop and start it)."""
    from tests.pg_server import INSTALL_HINT, PgServer, find_bindir

    if find_bindir() is None:
        pytest.skip(f"PostgreSQL server binaries (initdb, pg_ctl) not found: {INSTALL_HINT}")
    with PgServer.start_new() as server:
        yield server


def _capture(robot, tracker, db, *extra) -> list[str]:
    return [*CLI, "capture", "poses", "--count", str(POINTS), "--seed", "2", "--model", "ur10e",
            "--tool-mm", "0,0,60", "--no-floor", "--tracker-at", "2500,0,500",
            "--robot", robot, "--tracker", tracker,
            "--db", db, "--json", *extra]


def _wait_for(db, n, proc, timeout=60.0) -> None:
    deadline = time.monotonic() + timeout
    while count_samples(db) < n:
        assert proc.poll() is None, f"capture ended early (rc {proc.returncode})"
        assert time.monotonic() < deadline
        time.sleep(0.005)


def _check_every_point_once(db, robot_id=None, run_id=1):
    with RunStore(db) as store:
        r = store.run(run_id)
        s = store.samples(run_id)
        kinds = [k for _, _, k, _ in store.interruptions(run_id)]
    assert r.status == "completed"
    assert np.array_equal(s.point_index, np.arange(POINTS))  # no gaps, no duplicates
    if robot_id is not None:
        assert r.robot_id == robot_id
    return kinds


def _capture_with_outage(db, seed: str, store_wait: str, at: int, outage, then=None):
    """A capture over sockets into ``db``; ``outage(proc)`` once ``at`` samples are stored;
    ``then(summary)`` afterwards, the cell still served. Returns the exit code, the printed
    JSON and what ``then`` returned."""
    with sim_serve("--no-pty", "--seed", seed) as serve:
        urls = read_lines(serve, 3, timeout=30)
        p = subprocess.Popen(_capture(urls[1], urls[2], db, "--store-wait", store_wait),
                             cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        try:
            _wait_for(db, at, p)
            outage(p)
            out, _ = p.communicate(timeout=180)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()
        assert out, f"no output (rc {p.returncode})"
        summary = json.loads(out)
        return p.returncode, summary, None if then is None else then(summary)


@pytest.mark.slow
def test_server_restarted_mid_capture_the_run_waits_and_loses_nothing(own_pg):
    db = own_pg.create_database("restart")
    # every client loses its connection; the server is back after ~1-2 s
    rc, summary, _ = _capture_with_outage(db, "5", "120", 30, lambda _p: own_pg.restart())
    assert rc == 0, summary
    assert summary["status"] == "completed" and summary["samples"] == POINTS
    # the robot's id: MODEL/SERIAL as the simulated controller identifies itself
    kinds = _check_every_point_once(db, robot_id="SIMBOT-1/SIM-ur10e-5")
    assert kinds.count("store") == 1, kinds  # the wait is recorded, once it could be
    print(f"\nserver restarted mid-capture: {POINTS}/{POINTS}, interruptions {kinds}")


@pytest.mark.slow
def test_server_gone_longer_than_the_wait_pauses_then_resumes(own_pg):
    db = own_pg.create_database("gone")

    def away_until_paused(p):
        own_pg.stop()
        try:
            p.wait(timeout=120)
        finally:
            own_pg.start()

    def resume(_summary):
        return count_samples(db), subprocess.run([*CLI, "resume", "--db", db, "--json"],
                                                 cwd=ROOT, capture_output=True, timeout=180)

    rc, paused, (stored, resumed) = _capture_with_outage(db, "6", "1", 40, away_until_paused,
                                                         resume)
    assert rc == 1, paused
    assert paused["status"] == "paused" and "run store unreachable" in paused["reason"]
    assert paused["samples"] < POINTS and stored >= 40
    assert resumed.returncode == 0, resumed.stderr.decode()
    summary = json.loads(resumed.stdout)
    assert summary["status"] == "completed" and summary["samples"] == POINTS
    kinds = _check_every_point_once(db)
    # the pause could not be written while the server was away: resume found it running
    assert kinds.count("killed") == 1 and kinds.count("resume") == 1, kinds
    print(f"\nserver gone: paused with {paused['samples']} stored ({stored} in the store), "
          f"resumed to {POINTS}/{POINTS}; interruptions {kinds}")


@pytest.mark.slow
def test_two_cells_capture_into_one_database_at_once(pg_url):
    with sim_serve("--no-pty", "--seed", "7") as cell_a, \
            sim_serve("--no-pty", "--seed", "8") as cell_b:
        a, b = read_lines(cell_a, 3, timeout=30), read_lines(cell_b, 3, timeout=30)
        procs = [subprocess.Popen(_capture(urls[1], urls[2], pg_url, "--robot-id", name),
                                  cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
                 for urls, name in ((a, "cell-A"), (b, "cell-B"))]
        try:
            outs = [p.communicate(timeout=300) for p in procs]
        finally:
            for p in procs:
                if p.poll() is None:
                    p.kill()
                    p.wait()
    for p, (_out, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err.decode()
    runs = {json.loads(out)["run"]: name for (out, _), name in zip(outs, ("cell-A", "cell-B"),
                                                                     strict=True)}
    assert sorted(runs) == [1, 2]
    for run_id, name in runs.items():
        _check_every_point_once(pg_url, robot_id=name, run_id=run_id)
    with RunStore(pg_url) as store:
        a_run, b_run = (store.runs(name)[0] for name in ("cell-A", "cell-B"))
        order = [r[0] for r in store.db.execute("SELECT run_id FROM samples ORDER BY id"
                                                ).fetchall()]
    # they ran at once: the commits of the two cells interleave
    switches = sum(x != y for x, y in zip(order, order[1:], strict=False))
    assert switches >= 10, order
    assert a_run.robot_url != b_run.robot_url
    print(f"\ntwo cells into one database: runs {runs}, {len(order)} samples, the writer "
          f"switched {switches} times")
