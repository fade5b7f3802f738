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
import sys
from collections.abc import Iterator
from typing import Any

#: problems up to this many Jacobian elements (rows x parameters) run on one BLAS thread
SMALL_ELEMENTS = 4_000_000

#: modules whose import loads scipy's own BLAS (beside numpy's): the default calibrate
#: does not import scipy, a diagnosis does later, after the first identification
_SCIPY_BLAS = ("scipy.linalg", "scipy.special")

_controller: Any = None  # a threadpoolctl.ThreadpoolController (untyped library)
_controller_key: tuple[bool, ...] = ()


def _blas_controller() -> Any:
    """The process's :class:`threadpoolctl.ThreadpoolController` (made once, ~20 ms, and
    again when scipy's BLAS has been loaded since: a controller knows only the libraries
    loaded when it was made)."""
    global _controller, _controller_key
    key = tuple(m in sys.modules for m in _SCIPY_BLAS)
    if _controller is None or key != _controller_key:
        from threadpoolctl import ThreadpoolController

        _controller, _controller_key = ThreadpoolController(), key
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
