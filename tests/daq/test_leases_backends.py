"""Leases (one owner per run and per robot) on both backends: a SQLite file and a
PostgreSQL database (the ``leases`` table: store schema 5, :mod:`daq.store.schema`)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import pytest

from daq.store import RunStore
from daq.store.leases import LeaseBusy, Leases, run_key


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


@pytest.fixture
def store(store_address):
    with RunStore(store_address) as st:
        yield st


def test_one_owner_and_stale_owners_taken_over(store):
    # by address (a path or a URL: its own connection) or by the open store
    with Leases(store.address) as a, Leases(store, ttl_s=30.0) as b:
        assert a.acquire(run_key(1), "run 1") is None
        with pytest.raises(LeaseBusy, match=f"run 1 is in use by pid {os.getpid()}"):
            b.acquire(run_key(1), "run 1")
        a.release(run_key(1))
        assert b.acquire(run_key(1), "run 1") is None
        with pytest.raises(LeaseBusy):
            a.acquire(run_key(1), "run 1")
        host = a.host
    dead, now = _dead_pid(), time.time()
    for row in (("run:7", dead, host, now), ("run:8", 1, "elsewhere", now - 100.0),
                ("run:9", 1, "elsewhere", now)):
        store.db.execute("INSERT INTO leases VALUES (?, ?, ?, 'tok', 0, ?, ?)",
                         (*row, row[0].replace(":", " ")))
    with Leases(store, ttl_s=30.0) as c:
        assert c.acquire("run:7").pid == dead
        assert c.acquire("run:8").host == "elsewhere"
        with pytest.raises(LeaseBusy, match="pid 1 on elsewhere"):
            c.acquire("run:9")
        before = c._owner("run:7").heartbeat
        time.sleep(0.01)
        c.beat()
        assert c._owner("run:7").heartbeat > before
    with Leases(store) as d:  # released on exit
        assert d._owner("run:7") is None and d._owner("run:9") is not None


def test_racing_takers_get_one_owner(store):
    """Eight takers at once for one run: the take-over transaction is serialised."""
    won, busy, start = [], [], threading.Barrier(8)
    leases = [Leases(store) for _ in range(8)]

    def take(ls):
        start.wait()
        try:
            ls.acquire(run_key(3), "run 3")
            won.append(ls.token)
        except LeaseBusy:
            busy.append(ls.token)

    threads = [threading.Thread(target=take, args=(ls,)) for ls in leases]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert len(won) == 1 and len(busy) == 7
        assert leases[0]._owner(run_key(3)).token == won[0]
    finally:
        for ls in leases:
            ls.close()
