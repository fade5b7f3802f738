"""The chi distribution with 3 degrees of freedom (the norm of a 3-D Gaussian residual):
its tail and the quantile of a tail, in closed form.

The blunder test (:mod:`calibration.fit.outliers`) needs two numbers of it: its median and
the threshold a residual exceeds by chance with probability alpha / n. Three degrees of
freedom have an elementary tail, ``P(chi3 > k) = erfc(k/√2) + √(2/π) k e^(-k²/2)``, so
they come from :func:`math.erfc` and a few Newton steps instead of ``scipy.special``
(whose import is a third of a ``cellcal calibrate``); they agree with
``scipy.special.chdtri`` to rounding.
"""

from __future__ import annotations

import math

_C = math.sqrt(2.0 / math.pi)


def chi3_sf(k: float) -> float:
    """P(chi3 > k), the chi distribution's tail with 3 degrees of freedom."""
    if k <= 0.0:
        return 1.0
    return math.erfc(k / math.sqrt(2.0)) + _C * k * math.exp(-0.5 * k * k)


def chi3_isf(p: float) -> float:
    """k with ``P(chi3 > k) = p`` (0 < p < 1): Newton's method on ``log P(chi3 > k)``,
    bracketed, from the Wilson-Hilferty approximation."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"a tail probability must lie in (0, 1), not {p}")
    lo, hi = 0.0, 40.0  # P(chi3 > 40) is below 1e-340: every double p lies within
    z = -_normal_quantile_approx(p)
    k = math.sqrt(max(3.0 * (1.0 - 2.0 / 27.0 + z * math.sqrt(2.0 / 27.0)) ** 3, 1e-6))
    target = math.log(p)
    for _ in range(100):
        sf = chi3_sf(k)
        if sf == 0.0:  # beyond the doubles' range: too far out
            hi, k = k, 0.5 * (lo + k)
            continue
        f = math.log(sf) - target
        if f > 0:
            lo = k
        else:
            hi = k
        pdf = _C * k * k * math.exp(-0.5 * k * k)
        step = f * sf / pdf if pdf > 0 else math.inf
        new = k + step
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        if abs(new - k) <= 1e-15 * k:
            return new
        k = new
    return k


def _normal_quantile_approx(p: float) -> float:
    """A rough standard-normal quantile (a start for Newton's method, 1e-3 accurate)."""
    q = p if p < 0.5 else 1.0 - p
    t = math.sqrt(-2.0 * math.log(q))
    z = t - (2.515517 + 0.802853 * t + 0.010328 * t * t) / (
        1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t ** 3)
    return -z if p < 0.5 else z
