"""The F-test of a candidate effect: log10 of its p-value, from ``scipy.special`` exactly as
``scipy.stats`` computes it (scipy.stats takes a third of a second to import)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt


def log10_f_sf(d_rss: npt.ArrayLike, rss1: npt.ArrayLike, k: npt.ArrayLike,
               dof: npt.ArrayLike) -> Any:
    """log10 of the F-test's p-value (explained ``d_rss`` with ``k`` degrees of freedom
    against the remaining ``rss1`` with ``dof``), with an asymptotic tail where scipy
    underflows; scalars or arrays."""
    import scipy.special  # here: scipy's import is half of `cellcal calibrate`'s start-up

    d_rss, rss1, k, dof = np.broadcast_arrays(*(np.asarray(v, float)
                                                for v in (d_rss, rss1, k, dof)))
    F = (d_rss / k) / (rss1 / dof)
    lp = _f_logsf(F, k, dof)
    bad = ~np.isfinite(lp)
    if bad.any():
        # large dof: k F ~ chi2(k); log Q(a, x) ~ (a - 1) ln x - x - lgamma(a) for large x
        a, xx = k[bad] / 2.0, k[bad] * F[bad] / 2.0
        lp[bad] = (a - 1) * np.log(xx) - xx - scipy.special.gammaln(a)
    out = lp / math.log(10)
    return float(out) if out.ndim == 0 else out


def _f_logsf(F: np.ndarray, k: np.ndarray, dof: np.ndarray) -> np.ndarray:
    """``scipy.stats.f.logsf(F, k, dof)`` as scipy computes it (log of the upper tail above
    the median, log1p of minus the lower one below), from ``scipy.special``: scipy.stats
    takes a third of a second to import."""
    import scipy.special  # here: scipy's import is half of `cellcal calibrate`'s start-up

    above = scipy.special.fdtri(k, dof, 0.5) < F
    with np.errstate(divide="ignore"):
        return np.where(above, np.log(scipy.special.fdtrc(k, dof, F)),
                        np.log1p(-scipy.special.fdtr(k, dof, F)))
