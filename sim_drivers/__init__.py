"""A simulated cell: a true robot with hidden errors, a noisy tracker, faults, a clock,
served over the wire protocols the drivers speak and as in-process objects.

Modules
    ``truth``              the true-robot protocol and ``ToyArm``, a 3-joint stand-in
    ``model_truth``        ``ModelTruth``: a nominal model plus hidden errors and effects
    ``cell``               ``SimCell``: the true robot, its controller, the tracker, the clock
    ``thermal``            ``JointThermal``: joint temperatures that rise with work (off by default)
    ``beam``               the tracker's line of sight: facing, link capsules, fixtures
    ``tracker_optics``     the tracker's optics: refraction of air, reflector constants,
                           two-face error
    ``six_dof``            a 6-DoF target (a T-Mac) on the tool, as the tracker measures it
    ``refusals``           ``CellRefused``: what the cell says when it refuses a command
    ``faults``             fault injection: a spec language by probability or schedule
    ``inprocess``          ``sim://`` drivers acting directly on a shared cell
    ``line_server``        a line-protocol server thread over TCP or a pseudo-terminal
    ``robot_server``       the line-protocol robot controller
    ``tracker_server``     the line-protocol laser tracker
    ``emscon_server``      the laser tracker behind Leica's emScon TPI (the driver's codec)
    ``emscon_probe``       the emScon server's 6-DoF part: probe queries, the 6D result
    ``modbus_server``      the PLC-style robot controller over Modbus TCP
    ``rtde_wire``          the RTDE (protocol v2) wire format
    ``rtde_server``        an RTDE server for the cell (receive side of ur-rtde)
    ``rtde_child``         that server's child process
    ``fake_rtde_control``  ``FakeRTDEControl``: ur-rtde's control interface on a cell
    ``serve``              ``SimStack``: every server for one cell (``cellcal sim serve``)

Logging: the faults fired and the clients connected at INFO (``cellcal sim serve -v``);
no handler but a ``NullHandler`` (the application configures them).
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
