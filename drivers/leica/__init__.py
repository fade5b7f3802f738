"""Leica laser trackers over the emScon TPI (``emscon://host[:700]``).

:mod:`drivers.leica.enums` and :mod:`drivers.leica.codec` hold the packet
structs and enums of ``ES_C_API_Def.h`` (TPI/SDK 3.6), :mod:`drivers.leica.framing`
cuts a TCP stream into packets, :mod:`drivers.leica.driver` is the
:class:`EmsconTracker`. The simulator's server (``sim_drivers.emscon_server``)
uses the same codec.

Modules
    ``driver``         ``EmsconTracker``: the tracker behind ``emscon://host[:port]``
    ``metrology``      the tracker's metrology capabilities
    ``six_dof``        the 6-DoF capability: a T-Mac's pose
    ``link``           a TCP link: packets out, decoded packets in, every read with a deadline
    ``framing``        a byte stream cut into packets by their length prefix
    ``codec``          the packets: one class per C struct of ``ES_C_API_Def.h``
    ``probe_packets``  the 6-DoF (probe) structs of ``ES_C_API_Def.h``
    ``enums``          the enumerations, with the header's names and values
    ``units``          the unit enumerations as numbers: from cellcal's units and back
"""

from drivers.leica.driver import DEFAULT_PORT, STATUS_ERRORS, EmsconTracker

__all__ = ["DEFAULT_PORT", "STATUS_ERRORS", "EmsconTracker"]
