"""ABB robots over Robot Web Services 1.0 (IRC5, RobotWare 6): ``abb://host``.

The RAPID module the driver talks to is ``drivers/abb/rapid/CellcalServer.mod``; the
simulator's server (``sim_drivers.rws_server``) uses the same codec. docs/abb.md.

Modules
    ``codec``   the RWS resources, their JSON, RAPID's text for data, and the RAPID server
                module's protocol
    ``link``    the HTTP link: digest authentication, session cookies, timeouts, typed
                errors
    ``driver``  :class:`AbbRwsRobot`, the RobotDriver
"""

from drivers.abb.driver import AbbRwsRobot

__all__ = ["AbbRwsRobot"]
