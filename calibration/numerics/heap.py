"""Freed memory kept for the next arrays: glibc's heap top padded while calibrating.

A calibration's arrays are medium-sized: at 1 000 poses a Jacobian is 0.8 MB and one
evaluation of the chain makes dozens of 0.1-0.7 MB temporaries. glibc hands such blocks
out from the top of its heap, and gives a freed top beyond its trim threshold back to the
system; the next array of that size then faults its pages in again, each one zeroed by
the kernel. Measured at 1 000 poses on one thread: a Jacobian evaluation took 2.7 ms, of
which 0.8 ms computing and the rest page faults; a whole identification twice its
computing time.

:func:`keep_freed_memory` sets glibc's top pad (``M_TOP_PAD``) once per process: the heap
grows by at least that much and keeps that much free when it trims, so the temporaries of
one evaluation reuse the pages of the last. It also serves blocks up to 32 MiB from the
heap (``M_MMAP_THRESHOLD``; glibc's default maps each block over 128 kB on its own until a
freed one raises the threshold, so the first fits of a process, and a loop of fits whose
arrays grow, fault every page of every Jacobian in anew: at 1 000 poses, 150 000 page
faults and 0.9 s of system time in a 0.4 s calibrate on a busy machine). The cost is
memory the process keeps (:data:`TOP_PAD_BYTES` at the top, freed blocks below it until
the heap's top is free again; the peak is unchanged). Elsewhere than on glibc (macOS,
Windows, musl) nothing is changed.
"""

from __future__ import annotations

import ctypes
import sys

#: glibc's ``mallopt`` parameter numbers (malloc.h): the top pad, the trim threshold and
#: the size from which a block is mapped on its own
M_TOP_PAD = -2
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: free memory the heap keeps at its top
TOP_PAD_BYTES = 32 << 20
#: blocks up to this size come from the heap (glibc's largest allowed threshold), and the
#: heap gives back a free top only beyond twice that
MMAP_THRESHOLD_BYTES = 32 << 20

_kept = False


def keep_freed_memory(nbytes: int = TOP_PAD_BYTES) -> bool:
    """Let glibc's heap keep ``nbytes`` free at its top (once per process; later calls do
    nothing). Returns whether the setting is in force."""
    global _kept
    if _kept:
        return True
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    _kept = bool(mallopt(M_TOP_PAD, int(nbytes)))
    # arrays of a few megabytes (a Jacobian of thousands of poses) would otherwise be
    # mapped on their own and their pages faulted in again at every allocation
    mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
    mallopt(M_TRIM_THRESHOLD, 2 * MMAP_THRESHOLD_BYTES)
    return _kept
