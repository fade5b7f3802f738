"""Every driver whose device is gone (its server stopped) says so: ConnectionLost within
the call's timeout, and again on ``connect``."""

from __future__ import annotations

import pytest

from drivers.errors import ConnectionLost
from tests.drivers.rigs import ROBOTS, TRACKERS, having, serve_robot, serve_tracker
from tests.sim_drivers.helpers import MARGIN, elapsed_below

GONE = [("robot", n) for n in having(ROBOTS, "gone")] + \
       [("tracker", n) for n in having(TRACKERS, "gone")]


@pytest.mark.parametrize("role, name", GONE, ids=[f"{r}-{n}" for r, n in GONE])
def test_server_gone_is_connection_lost(role, name, cell):
    serve = serve_robot if role == "robot" else serve_tracker
    with serve(name, cell) as rig:
        rig.server.stop()
        with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost):
            rig.driver.status(timeout=1.0)
        with pytest.raises(ConnectionLost):
            rig.driver.connect(timeout=0.5)
