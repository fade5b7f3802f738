"""Leica laser trackers over the emScon TPI (``emscon://host[:700]``).

:mod:`drivers.leica.enums` and :mod:`drivers.leica.codec` hold the packet
structs and enums of ``ES_C_API_Def.h`` (TPI/SDK 3.6), :mod:`drivers.leica.framing`
cuts a TCP stream into packets, :mod:`drivers.leica.driver` is the
:class:`EmsconTracker`. The simulator's server (``sim_drivers.emscon_server``)
uses the same codec.
"""

from drivers.leica.driver import DEFAULT_PORT, STATUS_ERRORS, EmsconTracker

__all__ = ["DEFAULT_PORT", "STATUS_ERRORS", "EmsconTracker"]
