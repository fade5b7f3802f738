"""The application's own error: bad usage of a command (exit code 2, docs/formats.md §6).

The layers below raise their own families (``calibration.errors``, ``daq.errors``,
``daq.store.errors``, ``drivers.errors``), each class carrying its exit code;
:func:`cellcal.cli.main` maps them all in one place.
"""

from __future__ import annotations


class UsageError(Exception):
    """Bad input from the user: printed without a traceback, exit code 2."""

    exit_code = 2
