"""The URL schemes the application adds to the drivers' own: ``sim://``, the simulated cell
in process (:mod:`sim_drivers.inprocess`).

:mod:`drivers.urls` registers the real cell's schemes itself and never imports the
simulator; the capture service (:mod:`daq`) opens whatever URL it is given. So the
application registers ``sim`` when it starts (:func:`register_schemes`, called by
:func:`cellcal.cli.main`; the test suite's ``conftest.py`` does the same), with an opener
that loads the simulator at the first ``sim://`` URL: a capture on the real cell never
imports it.

Registered explicitly rather than by a Python entry point: an entry point needs the
package installed (its metadata), so a source checkout on ``PYTHONPATH`` would not know
``sim://``, and ``drivers`` would load ``sim_drivers`` by a name the import contracts
(``lint-imports``) cannot see.
"""

from __future__ import annotations

from typing import Any

from drivers.urls import Kind, register_scheme


def open_sim(url: str, kind: Kind, /, **kw: Any) -> Any:
    """The ``sim://`` opener: :func:`sim_drivers.inprocess.open_sim`, loaded when first used."""
    from sim_drivers.inprocess import open_sim as open_in_process  # not for the real cell

    return open_in_process(url, kind, **kw)


def register_schemes() -> None:
    """Register the application's URL schemes (``sim``) with :mod:`drivers.urls`."""
    register_scheme("sim", open_sim)
