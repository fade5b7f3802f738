"""The simulated tracker's optics: refraction of air, reflector constants, two-face error.

Pure functions and data used by :class:`~sim_drivers.cell.SimCell` to turn the
true target position into what the tracker reads. Distances scale by
``n_true / n_used`` (:func:`refractive_index`, the NIST shop-floor equation for
~633 nm): air given 1 °C too warm reads ~0.93 µm per metre too long. A
collimation error turns the point about the tracker's vertical (z) axis, with
opposite signs in the two faces.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SimReflector:
    """A reflector the simulated tracker knows (``constant_mm``: where its optical
    zero lies behind the sphere centre, along the beam; 0 for air-path corner cubes)."""

    id: int
    name: str
    target_type: str
    surface_offset_mm: float
    constant_mm: float = 0.0


#: the simulated tracker's reflector list (ids, names and constants made up for the simulator)
TRACKER_REFLECTORS = (
    SimReflector(1, "RRR 1.5in", "ES_TT_RRR15", 19.05),
    SimReflector(2, "RRR 0.5in", "ES_TT_RRR05", 6.35),
    SimReflector(3, "BRR 1.5in", "ES_TT_BRR15", 19.05),
    SimReflector(4, "TBR 0.5in", "ES_TT_TBR05", 6.35, 0.035),
    SimReflector(5, "CatsEye 3in", "ES_TT_CatsEye", 38.1, 0.25),
)


def refractive_index(temp_c: float, pressure_hpa: float, humidity_pct: float) -> float:
    """Refractive index of air (NIST shop-floor equation, ~633 nm):
    ``1 + 7.86e-4·p/(273 + t) − 1.5e-11·RH·(t² + 160)``, p in kPa."""
    p_kpa = pressure_hpa / 10.0
    return 1.0 + 7.86e-4 * p_kpa / (273.0 + temp_c) - 1.5e-11 * humidity_pct * (
        temp_c**2 + 160.0)


def tracker_reads(p: np.ndarray, used_air: Sequence[float], true_air: Sequence[float],
                  constant_mm: float = 0.0, collimation_rad: float = 0.0) -> np.ndarray:
    """Where the tracker puts the true point ``p`` (mm, tracker frame).

    ``used_air`` / ``true_air``: (°C, hPa, %RH) the tracker corrects with / the
    air really has; ``constant_mm`` added to the distance (mounted minus selected
    reflector constant); ``collimation_rad`` the turn about z (signed by face).
    """
    p = np.asarray(p, float)
    dist = float(np.linalg.norm(p))
    if dist == 0:
        return p.copy()
    d = dist * refractive_index(*true_air) / refractive_index(*used_air) + constant_mm
    q = p * (d / dist)
    if collimation_rad:
        c, s = np.cos(collimation_rad), np.sin(collimation_rad)
        q = np.array([c * q[0] - s * q[1], s * q[0] + c * q[1], q[2]])
    return q
