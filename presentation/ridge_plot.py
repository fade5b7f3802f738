"""The ridge solver's diagnostics as a figure: L-curve, GCV and ridge trace
(``cellcal calibrate --solver ridge --ridge-plot FILE.png``)."""

from __future__ import annotations

import numpy as np

from calibration.files import atomic_output
from calibration.fit.solvers.ridge import gcv


def plot_ridge(info: dict, path, title: str = "") -> None:
    """Save the L-curve, GCV and ridge trace of a ridge fit as a PNG (matplotlib, Agg).

    Parameters
    ----------
    info : ``SolverResult.info`` / ``Fit.info`` of a ``ridge`` fit
    path : output file (.png)
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = info["ridge_curve"]
    k = curve["xi"] > 0
    xi = curve["xi"][k]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    ax[0].loglog(curve["residual_norm"][k], curve["solution_norm"][k], ".-")
    j = int(np.argmin(np.abs(np.log(xi) - np.log(max(info["xi"], xi[0])))))
    ax[0].loglog(curve["residual_norm"][k][j], curve["solution_norm"][k][j], "ro",
                 label=f"chosen xi = {info['xi']:.3g} ({info['xi_method']})")
    ax[0].set_xlabel("weighted residual norm, mm")
    ax[0].set_ylabel("|u| (equilibrated deviation from start)")
    ax[0].set_title("L-curve")
    ax[0].legend()
    n_obs = 3 * int(np.count_nonzero(np.asarray(info["weights"]) > 0))
    ax[1].loglog(xi, gcv(curve, n_obs)[k])
    ax[1].axvline(max(info["xi"], xi[0]), color="r")
    ax[1].set_xlabel("ridge parameter xi")
    ax[1].set_ylabel("GCV(xi)")
    ax[1].set_title("generalised cross-validation")
    ax[2].semilogx(xi, curve["trace"][k])
    ax[2].axvline(max(info["xi"], xi[0]), color="r")
    ax[2].set_xlabel("ridge parameter xi")
    ax[2].set_ylabel("u_k (equilibrated parameter deviation)")
    ax[2].set_title(f"ridge trace ({curve['trace'].shape[1]} parameters)")
    fig.suptitle(title or f"ridge: condition number {info['condition_number']:.3g} "
                 f"({info['condition_class']})")
    fig.tight_layout()
    with atomic_output(path) as tmp:  # the old plot stays whole if saving fails
        fig.savefig(tmp, dpi=100)
    plt.close(fig)
