"""What the simulated cell says when it refuses a command: :class:`CellRefused`.

Apart from :mod:`sim_drivers.cell` so that the cell's parts (the 6-DoF measurement of
:mod:`sim_drivers.six_dof`) refuse with the same error the servers put on the wire;
``sim_drivers.cell`` re-exports it.
"""

from __future__ import annotations


class CellRefused(Exception):  # noqa: N818 - a refusal, not a bug
    """The simulated controller or tracker refuses a command.

    ``name`` is the protocol's error name (``LIMIT``, ``PROTECTIVE_STOP``,
    ``BEAM_BROKEN``...), which the servers put on the wire.
    """

    def __init__(self, name: str, detail: str = "") -> None:
        self.name = name
        self.detail = detail
        super().__init__(f"{name}: {detail}" if detail else name)
