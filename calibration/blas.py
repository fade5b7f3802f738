"""BLAS threads for small problems: one.

A calibration's matrices are small (1 000 poses x 35 parameters: 3 000 x 35). Splitting
their products over BLAS threads gains little on an idle machine and costs a lot on a
busy one: a thread that waits for a core another process holds stalls the whole product
(1 000 poses identified in ~50 ms with one thread, 570-650 ms with the default two while
another process saturated a core). :func:`blas_threads` pins BLAS to one thread while a
problem is small (threadpoolctl), so timings do not depend on the neighbours.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

#: problems up to this many Jacobian elements (rows x parameters) run on one BLAS thread
SMALL_ELEMENTS = 4_000_000

_controller = None


def _blas_controller():
    """The process's :class:`threadpoolctl.ThreadpoolController` (made once: ~20 ms)."""
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    return _controller


@contextlib.contextmanager
def blas_threads(n_elements: int, small: int | None = None) -> Iterator[None]:
    """One BLAS thread inside the block when ``n_elements <= small`` (default
    :data:`SMALL_ELEMENTS`, read at the call: a benchmark may set it to -1 to compare);
    else unchanged."""
    if n_elements > (SMALL_ELEMENTS if small is None else small):
        yield
        return
    with _blas_controller().limit(limits=1, user_api="blas"):
        yield
