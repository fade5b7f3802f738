"""A correction table as a screening candidate: knots over the data's angles, spacing and
smoothing by GCV on the linearised problem (:func:`screen_table`), its normal equations
from per-pose products without forming its 3n x k columns."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..effects.table import SMOOTHING_GRID, Table, penalised_path
from .candidate_columns import joint_partials, valid_columns
from .linear_screen import Linearised, Screened, as_screened, evaluate_candidates

#: knot spacings (degrees) a table candidate is tried at; GCV picks one per joint
TABLE_SPACINGS_DEG = (10, 5, 3, 2)
#: a finer table spacing is chosen only when its GCV is lower than a coarser one's by more
#: than this (relative): the GCV of the 2 000-pose benchmark's tables moves by up to 1e-9
#: between BLAS kernels (Haswell, SkylakeX, Sandybridge), while its genuine differences
#: between spacings are 1e-7 and more; a tie within rounding goes to the coarser table
#: (fewer parameters), the same on every machine
GCV_TIE_RTOL = 1e-8


def data_gap_deg(theta_rad: np.ndarray, trim: float = 1.0) -> float:
    """The widest gap (degrees) between consecutive angles in the middle of the data (the
    ``trim`` % at either end left out): a table's knots are no closer than this, so that no
    stretch between knots is left to the smoothness penalty alone (a table cannot predict
    across a gap in the data; a formula can)."""
    t = np.sort(np.degrees(np.asarray(theta_rad, float)))
    if t.size < 3:
        return float("inf")
    lo, hi = np.percentile(t, [trim, 100 - trim])
    mid = t[(t >= lo) & (t <= hi)]
    return float(np.diff(mid).max()) if mid.size > 1 else float("inf")


def screen_table(lin: Linearised, joint: int,
                 spacings: Sequence[int]) -> Screened | None:
    """The best table on ``joint``: knots over the calibration rows' angles, only those the
    rows support (:meth:`Table.supported`: constant beyond; validation rows, which the
    table is not fitted to, add no knot), spacing (no finer than the data's widest gap,
    :func:`data_gap_deg`; a finer one only when its GCV is lower by more than
    :data:`GCV_TIE_RTOL`) and smoothing by GCV on the linearised problem."""
    fit = lin.fit
    em = fit.error_model
    theta = lin.calib.q[:, joint - 1]
    n = lin.n
    best = None
    curves = {}
    finest = data_gap_deg(lin.calib.q[:, joint - 1])
    products = None
    usable = [sp for sp in spacings if sp >= finest] or [max(spacings)]
    for spacing in usable:
        if np.ptp(np.degrees(theta)) < 2 * spacing:
            continue
        table = Table.supported(em.model, joint, theta, spacing)
        B = joint_partials(table, lin.calib, lin.bound)
        if products is None:
            products = _joint_products(lin, joint)
        VtV, Ctr, Vtr = _table_normal(products, B)
        path = penalised_path(VtV, Ctr, Vtr, VtV, lin.rss0, table.penalty_matrix(),
                              SMOOTHING_GRID, 3 * n, lin.trace0)
        g = float(path["gcv"][path["best"]])
        curves[spacing] = [(float(s), float(np.sqrt(3 * v))) for s, v in
                           zip(path["grid"], path["gcv"], strict=True)]
        if best is None or g < best[0] * (1.0 - GCV_TIE_RTOL):
            best = (g, table, B, float(path["grid"][path["best"]]))
    if best is None:
        return None
    _, table, B, s = best
    C = lin.G[:, :, joint - 1, None] * B[:, None, :]  # effect_columns of a joint effect
    table.smoothing = s
    table.cv_curve = curves[int(table.spacing_deg)]
    Cv = valid_columns(table, lin, em, fit.values)
    if Cv is not None:
        Cv = Cv[:, :, None]
    res = evaluate_candidates(lin, C[:, :, None], Cv, table.penalty_matrix(), s)
    return as_screened(lin, table, {k: v[0] for k, v in res.items()},
                     gcv_by_spacing={sp: min(v for _, v in cv) for sp, cv in curves.items()})


def _joint_products(lin: Linearised, joint: int) -> tuple:
    """What every table on ``joint`` shares (a table's columns are ``C_i = g_i b_iᵀ``, g_i
    = dP_i/dq_joint, b_i its basis at pose i): U = (W_iᵀ g_i) (m, n), |g_i|² and g_iᵀ r_i
    (n,), Wᵀ r (m,) and Wᵀ W (m, m)."""
    n = lin.n
    g = lin.G[:, :, joint - 1]
    U = np.einsum("nim,ni->mn", lin.W.reshape(n, 3, -1), g)
    if lin.WtW is None:
        lin.WtW = lin.W.T @ lin.W
    return U, np.sum(g * g, axis=1), np.sum(g * lin.r, axis=1), lin.W.T @ lin.r.ravel(), \
        lin.WtW


def _table_normal(products: tuple, B: np.ndarray) -> tuple:
    """VᵀV, Cᵀr and Vᵀr of a table with basis B (n, k) from :func:`_joint_products`,
    without forming C or V = C - W WᵀC (3n x k each): with Y = WᵀC = U B,
    ``VᵀV = CᵀC - 2 YᵀY + Yᵀ (WᵀW) Y`` and ``CᵀC = Bᵀ diag(|g_i|²) B`` (n rows, not 3n),
    ``Vᵀr = Cᵀr - Yᵀ Wᵀr``. A third of the work; the same numbers to rounding."""
    U, gg, gr, Wr, WtW = products
    Y = U @ B
    VtV = B.T @ (gg[:, None] * B) - 2.0 * (Y.T @ Y) + Y.T @ (WtW @ Y)
    VtV = 0.5 * (VtV + VtV.T)
    Ctr = B.T @ gr
    return VtV, Ctr, Ctr - Y.T @ Wr
