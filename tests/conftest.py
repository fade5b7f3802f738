"""Suite-wide fixtures: leak checks, opt-in hardware options, the ``sim://`` scheme.

Every test must leave no thread, child process or socket behind: the
``no_leaks`` fixture (autouse) fails a test that does.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time

import pytest

from cellcal.url_schemes import register_schemes


@pytest.fixture(autouse=True, scope="session")
def sim_scheme():
    """``sim://`` URLs open in every test, as in the application (which registers the
    scheme when it starts: :mod:`cellcal.url_schemes`)."""
    register_schemes()


@pytest.fixture(autouse=True, scope="session")
def run_log_dir(tmp_path_factory):
    """The logs of PostgreSQL stores' runs (written in the current directory by default:
    cellcal.logs.run_log_path) go to a folder of the session's own, subprocesses included."""
    old = os.environ.get("CELLCAL_RUN_LOG_DIR")
    os.environ["CELLCAL_RUN_LOG_DIR"] = str(tmp_path_factory.mktemp("run_logs"))
    yield
    if old is None:
        os.environ.pop("CELLCAL_RUN_LOG_DIR", None)
    else:
        os.environ["CELLCAL_RUN_LOG_DIR"] = old


def pytest_addoption(parser):
    parser.addoption("--robot-url", default=None, help="URL of a real robot controller")
    parser.addoption("--tracker-url", default=None, help="URL of a real laser tracker")


@pytest.fixture
def robot_url(request):
    url = request.config.getoption("--robot-url")
    if not url:
        pytest.skip("needs --robot-url (real hardware)")
    return url


@pytest.fixture
def tracker_url(request):
    url = request.config.getoption("--tracker-url")
    if not url:
        pytest.skip("needs --tracker-url (real hardware)")
    return url


def _sockets() -> set[str]:
    out = set()
    try:
        for fd in os.listdir("/proc/self/fd"):
            try:
                target = os.readlink(f"/proc/self/fd/{fd}")
            except OSError:
                continue
            if target.startswith("socket:"):
                out.add(target)
    except FileNotFoundError:  # not Linux
        pass
    return out


def _live_threads() -> set[threading.Thread]:
    return {t for t in threading.enumerate() if t.is_alive()}


@pytest.fixture(autouse=True)
def no_leaks():
    """Fail a test that leaves threads, child processes or sockets behind."""
    threads0, sockets0 = _live_threads(), _sockets()
    yield
    deadline = time.monotonic() + 3.0
    while True:
        threads = {t for t in _live_threads() - threads0 if not t.daemon or t.is_alive()}
        children = multiprocessing.active_children()
        sockets = _sockets() - sockets0
        if not (threads or children or sockets) or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    problems = []
    if threads:
        problems.append(f"threads left running: {sorted(t.name for t in threads)}")
    if children:
        problems.append(f"child processes left running: {[p.pid for p in children]}")
        for p in children:
            p.kill()
    if sockets:
        problems.append(f"{len(sockets)} socket(s) left open")
    if problems:
        pytest.fail("leak: " + "; ".join(problems), pytrace=False)


# ------------------------------------------------------------------ PostgreSQL
@pytest.fixture(scope="session")
def pg_server():
    """A throwaway PostgreSQL server for the session (:mod:`tests.pg_server`); skipped only
    when the server binaries are not installed, and never in CI (``.ci/run`` installs them
    and sets ``CELLCAL_REQUIRE_POSTGRES=1``: a missing server fails there)."""
    import os

    from tests.pg_server import INSTALL_HINT, PgServer, find_bindir

    if find_bindir() is None:
        why = f"PostgreSQL server binaries (initdb, pg_ctl) not found: {INSTALL_HINT}"
        if os.environ.get("CELLCAL_REQUIRE_POSTGRES") == "1":
            pytest.fail(why, pytrace=False)
        pytest.skip(why)
    with PgServer.start_new() as server:
        yield server


_db_counter = iter(range(10**6))


@pytest.fixture
def pg_url(pg_server):
    """A new, empty database on the session's server (dropped afterwards): its URL."""
    name = f"t{os.getpid()}_{next(_db_counter)}"
    url = pg_server.create_database(name)
    yield url
    pg_server.drop_database(name)


@pytest.fixture(params=["sqlite", "postgresql"])
def store_address(request, tmp_path):
    """A run store address of each backend: a new SQLite file, a new PostgreSQL database."""
    if request.param == "sqlite":
        return str(tmp_path / "cell.db")
    return request.getfixturevalue("pg_url")
