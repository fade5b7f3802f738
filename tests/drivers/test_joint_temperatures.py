"""Joint temperatures travel from the (simulated) controller through every robot protocol:
ur-rtde's getJointTemperatures over RTDE, the Modbus joint_temps registers, the line
protocol's TEMPS? (issue 26; that each driver reads the cell's: the conformance suite,
tests/drivers/conformance/); a controller without them is refused, not guessed."""

import numpy as np
import pytest

from drivers.errors import CommandRejected
from drivers.modbus_robot import RegisterMap
from sim_drivers.cell import SimCell
from sim_drivers.model_truth import ModelTruth
from sim_drivers.rtde_server import IDLE_JOINT_TEMP_C
from tests.drivers.rigs import serve_robot


def test_controllers_without_temperatures_refuse():
    # a controller that reports none (a simulated one with no thermal model reports the
    # air's temperature: issue 36)
    cell = SimCell(ModelTruth.from_spec("ur10e", None, 2), seed=2, joint_temps=False)
    for kind, refusal in (("line-tcp", "BAD_COMMAND"), ("modbus", "exception 2"),
                          ("sim", "no joint temperatures")):
        with serve_robot(kind, cell) as rig:
            with pytest.raises(CommandRejected, match=refusal):
                rig.driver.joint_temperatures()
            rig.driver.read_joints()  # the link is fine
    custom = RegisterMap(status=200, error_code=201, heartbeat=202, command_ack=203,
                         joint_count=204, actual_joints=210, actual_tcp=230)
    assert custom.joint_temps is None and "joint_temps" not in custom.fields()
    with serve_robot("ur-rtde", cell, read_only=True) as rig:
        # a UR always streams them: a cell that reports none says 30 °C
        assert rig.driver.joint_temperatures() == (IDLE_JOINT_TEMP_C,) * 6


def test_temperature_registers_are_signed_centidegrees():
    regs = RegisterMap.pack_temps([24.37, -3.5, 0.0])
    assert regs == [2437, 65536 - 350, 0]
    np.testing.assert_allclose(RegisterMap.unpack_temps(regs), [24.37, -3.5, 0.0])
