"""Numerics the fits stand on: dense linear algebra, a distribution, BLAS threads, the heap,
the memory a command needs.

Modules
-------
linalg  Cholesky solves and pivoted QR on numpy alone (no scipy on calibrate's path)
chi3    the chi distribution with 3 degrees of freedom: tail and quantile
blas    one BLAS thread for small problems (timings independent of the neighbours)
heap    freed memory kept for the next arrays while calibrating (glibc's heap top)
memory  the memory a command over n poses needs, what is left, a refusal before starting
"""
