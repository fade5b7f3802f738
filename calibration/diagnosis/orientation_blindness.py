"""Where a position-only calibration is blind: the tool orientation it cannot check.

Positions of one SMR close to the last axis hardly see the wrist's orientation: a
calibration can fit every position to the noise floor and still turn the tool by
a tenth of a degree. :func:`orientation_blindness` says how far, from the data's own
poses, without any orientation measured:

- the parameters' uncertainty after the position rows, with a prior of the size real
  robots' errors have (:data:`PRIOR_FACTOR` times each effect's typical scale; the
  absolute base and tool parameters have none), so that what positions leave
  undetermined (the null space) counts at a plausible size instead of infinity;
- propagated to the flange's orientation at each pose, in the flange frame, minus its
  mean over the poses: a constant turn in the flange is where the tool (or a 6-DoF
  target) is mounted, which no robot calibration can tell from the target's mounting;
- the RMS over the poses of that orientation uncertainty (1 sigma, deg) is the error a
  position-only calibration could hide; the same with orientation rows added (a 6-DoF
  target of uncertainty ``sigma_deg``) is what measuring them would leave.

The result names the parameters that carry most of it, and says what to measure.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..fit.error_model import ErrorModel
from ..fit.identify import Fit

#: the prior's standard deviation, in units of each parameter's typical scale
PRIOR_FACTOR = 3.0
#: families without a prior: absolute values, not errors
ABSOLUTE_FAMILIES = ("base", "tool", "tool_rotation")
#: a 6-DoF target's orientation uncertainty when the data do not say (deg, a T-Mac's)
TARGET_SIGMA_DEG = 0.01
#: the blindness is reported when the hidden error exceeds this many target sigmas
WARN_FACTOR = 2.0

ADVICE = ("measure orientations: a 6-DoF target (qw, qx, qy, qz and sigma_deg columns, "
          "effect tool_rotation), or two or three SMR nests on the tool, each row naming "
          "its nest (tool_id column)")


@dataclass
class Blindness:
    """What positions leave undetermined of the tool's orientation.

    Attributes
    ----------
    hidden_deg : RMS over the poses of the orientation uncertainty after a position-only
        calibration (1 sigma), deg
    with_orientation_deg : the same when orientations (``sigma_deg``) are measured too
    sigma_deg : the orientation uncertainty assumed for that
    parameters : the parameters that carry most of ``hidden_deg``, largest first
    blind : True when ``hidden_deg`` exceeds ``WARN_FACTOR`` times ``sigma_deg``
    """

    hidden_deg: float
    with_orientation_deg: float
    sigma_deg: float
    parameters: list[str] = field(default_factory=list)
    blind: bool = False

    def note(self) -> str:
        """The warning for the user (meaningful when :attr:`blind`)."""
        return (f"position-only calibration: the tool's orientation is weakly determined: it "
                f"could be off by {self.hidden_deg:.3g} deg (RMS over these poses, 1 sigma) "
                f"with every position fitted (mostly {', '.join(self.parameters)}); "
                f"{ADVICE}, which would leave {self.with_orientation_deg:.2g} deg")

    def to_json(self) -> dict:
        return {"hidden_deg": self.hidden_deg,
                "with_orientation_deg": self.with_orientation_deg,
                "sigma_deg": self.sigma_deg, "parameters": list(self.parameters),
                "blind": self.blind, "advice": ADVICE}


def orientation_blindness(fit: Fit, sigma_deg: float | None = None) -> Blindness | None:
    """How much tool orientation the position-only ``fit`` leaves undetermined (see the
    module docstring); None for a full-pose fit or a model without a chain to turn."""
    if fit.orientation_fitted:
        return None
    em, data = fit.error_model, fit.data
    bound = em.bind(data)
    _, J, R, W = em.evaluate_pose(fit.values, bound, jacobian=True)
    # the orientation in the flange frame, less its mean over the poses (the mounting)
    Wf = np.swapaxes(R, 1, 2) @ W
    Wc = Wf - Wf.mean(axis=0)
    Jp = J.reshape(-1, em.n_params)
    Wo = Wc.reshape(-1, em.n_params)
    live = (np.linalg.norm(Jp, axis=0) > 0) | (np.linalg.norm(Wo, axis=0) > 0)
    sigma_mm = data.sigma() or fit.sigma_mm
    if not live.any() or not np.isfinite(sigma_mm) or sigma_mm <= 0:
        return None
    if sigma_deg is None:
        sigma_deg = (float(np.sqrt(np.mean(data.sigma_deg**2))) if data.sigma_deg is not None
                     else TARGET_SIGMA_DEG)
    prior = _prior_precision(em)[live]
    Jp, Wo = Jp[:, live], Wo[:, live]
    WtW = Wo.T @ Wo
    info_pos = Jp.T @ Jp / sigma_mm**2 + np.diag(prior)
    info_full = info_pos + WtW / np.radians(sigma_deg) ** 2
    n = data.n
    # trace(Wo C Woᵀ) = trace(C WoᵀWo): p x p products only, never the 3n x 3n matrix
    C_pos = np.linalg.pinv(info_pos, hermitian=True)
    # each parameter's share of the trace: diag(C WᵀW) sums to it (a redundant pair's
    # invisible combination adds nothing)
    share = np.einsum("ij,ji->i", C_pos, WtW)
    hidden = float(np.degrees(np.sqrt(max(share.sum(), 0.0) / n)))
    C_full = np.linalg.pinv(info_full, hermitian=True)
    with_o = float(np.degrees(np.sqrt(max(np.einsum("ij,ji->", C_full, WtW), 0.0) / n)))
    names = np.array(em.names)[live]
    top = [str(names[k]) for k in np.argsort(-share)[:3] if share[k] > 0.1 * share.max()]
    return Blindness(hidden, with_o, float(sigma_deg), top,
                     hidden > WARN_FACTOR * sigma_deg)


def _prior_precision(em: ErrorModel) -> np.ndarray:
    """(p,) the prior's precision per parameter: zero for absolute ones."""
    out = np.zeros(em.n_params)
    for e, sl in zip(em.effects, em.slices, strict=True):
        if e.family not in ABSOLUTE_FAMILIES:
            out[sl] = 1.0 / (PRIOR_FACTOR * np.asarray(e.scales, float)) ** 2
    return out
