"""The simulated cell's default ports and their flags (``cellcal sim serve``)."""

from __future__ import annotations

#: the default ports (also in :data:`sim_drivers.serve.DEFAULT_PORTS`, kept equal by
#: tests/cellcal/test_cli_help.py) and their flags: Modbus robot, line robot, line tracker,
#: emScon tracker
DEFAULT_PORTS = {"modbus": 15020, "line_robot": 15021, "tracker": 15700, "emscon": 15701}
PORT_FLAGS = {"modbus": "--modbus-port", "line_robot": "--line-robot-port",
              "tracker": "--tracker-port", "emscon": "--emscon-port"}
#: the ABB robot's port (Robot Web Services, served with --abb; ``--port-base N``: N+4) and
#: its flag (:data:`sim_drivers.serve.ABB_PORT`)
ABB_PORT, ABB_PORT_FLAG = 15080, "--abb-port"
