"""ABB robots over Robot Web Services 1.0 (IRC5, RobotWare 6): ``abb://host``.

:mod:`drivers.abb.codec` holds the resources, their JSON, RAPID's text for data and the
RAPID server module's protocol; :mod:`drivers.abb.link` the HTTP link (digest
authentication, session cookies, timeouts); :mod:`drivers.abb.driver` the
:class:`AbbRwsRobot`. The RAPID module the driver talks to is
``drivers/abb/rapid/CellcalServer.mod``. The simulator's server
(``sim_drivers.rws_server``) uses the same codec. docs/abb.md.
"""

from drivers.abb.driver import AbbRwsRobot

__all__ = ["AbbRwsRobot"]
