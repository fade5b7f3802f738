"""Cut a byte stream into emScon TPI packets by their length prefix, and nothing more.

Every emScon packet starts with ``PacketHeaderT {long lPacketSize; enum
ES_DataType type;}``, little-endian 32-bit integers, ``lPacketSize`` counting
the whole packet. :class:`FrameReader` is fed whatever ``recv`` returned (a
fraction of a packet, several packets, anything in between) and hands back
complete packets as bytes. It knows no packet's meaning: decoding is
:mod:`drivers.leica.codec`'s job.

A length outside ``[MIN_PACKET, max_packet]`` means the stream is not emScon
(or lost its alignment): :class:`FramingError`, after which the reader must be
cleared and the link resynchronised (reconnected).
"""

from __future__ import annotations

import struct

#: the smallest packet of the protocol: a header and one 32-bit field
#: (BasicCommandCT, SystemStatusChangeT)
MIN_PACKET = 12
#: the largest packet accepted by default; the longest struct of the TPI 3.6 header
#: (GetCompensations2RT) has 672 bytes
MAX_PACKET = 4096

_SIZE = struct.Struct("<i")


class FramingError(ValueError):
    """The byte stream cannot be cut into packets (a length prefix out of range)."""


class FrameReader:
    """Reassemble length-prefixed packets from arbitrary chunks.

    Parameters
    ----------
    max_packet : int
        Largest ``lPacketSize`` accepted.
    """

    def __init__(self, max_packet: int = MAX_PACKET) -> None:
        self.max_packet = int(max_packet)
        self._buf = bytearray()

    @property
    def pending(self) -> int:
        """Bytes received that do not yet form a whole packet."""
        return len(self._buf)

    def clear(self) -> None:
        """Forget buffered bytes (after a reconnect)."""
        self._buf.clear()

    def feed(self, data: bytes) -> list[bytes]:
        """Add ``data``; return every packet now complete, in order (possibly none).

        Raises :class:`FramingError` when a length prefix is out of range; the
        packets completed before it in this call are lost with the stream.
        """
        self._buf.extend(data)
        out: list[bytes] = []
        while len(self._buf) >= _SIZE.size:
            (size,) = _SIZE.unpack_from(self._buf, 0)
            if not MIN_PACKET <= size <= self.max_packet:
                head = bytes(self._buf[:16])
                self._buf.clear()
                raise FramingError(
                    f"packet length {size} outside {MIN_PACKET}..{self.max_packet} "
                    f"(stream starts {head.hex(' ')})"
                )
            if len(self._buf) < size:
                break
            out.append(bytes(self._buf[:size]))
            del self._buf[:size]
        return out
