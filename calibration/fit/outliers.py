"""Blunders: measurements far out of line with the rest, found, named and left out.

A laser tracker's blunders are 0.5-5 mm errors of single readings (the beam re-acquired
on a wrong return, the SMR re-seated, the robot not yet still, someone in the beam).
Least squares spreads each of them over every parameter; they must be left out, and
named so that someone can look at them, but never "explained" by a physical effect.

The test (:func:`find_blunders`)
--------------------------------
Each calibration point's residual ``r_i`` is studentised, ``(I - H_ii)^(-1/2) r_i`` with
``H_ii`` the point's 3x3 block of the fit's hat matrix (a point the fit leans on, such
as the only one near a correction-table knot, has a small residual even when it is a
blunder; a point left out of the fit: ``(I + H_ii)``, its prediction's variance), and
its norm divided by the instrument's uncertainty of that point ``s_i`` (the ``sigma_mm``
column, else the tracker sigma of the metadata or ``--sigma``; 1 mm when unknown):
``u_i``. For a model at the noise floor ``u`` follows a chi distribution with 3 degrees
of freedom. The bulk's robust scale is

    c = max(median(u) / 1.5382, MAD(u) / 0.4602, 1)

(median and median absolute deviation of chi(3); the MAD term widens the scale when the
bulk is spread more than a Gaussian cloud, e.g. by a missing effect; the 1 is the
instrument's own uncertainty, the lower bound: residuals at the noise floor are never
out of line). A point is out of line when ``u_i > k c`` with ``k`` the chi(3) quantile
at ``1 - alpha / n`` (Bonferroni: a clean Gaussian cloud of any size has a chance
``alpha`` of one false alarm; k = 4.7 for 150 points, 5.1 for 1000).

A cloud with a few blunders has a few such points. When more than ``max_fraction`` of
the points (6 %) are out of line, the residuals are not a clean cloud with a few
blunders (an incomplete model, a wrong nominal model, a drifting cell): nothing is
left out and the result says so (``clean_cloud`` False), pointing to ``diagnose``.

The loop (:func:`screen_fit`)
-----------------------------
Fit every point; test; refit without the points out of line (warm start, same solver);
test *every* point again at the new parameters (a point wrongly left out comes back),
until the set no longer changes. An excluded point's residual is then its distance
from what the other points predict. Large blunders can drag a least-squares fit (a
flexible one most) until many points look out of line: when the first test finds too
many, the worst ``max_fraction`` are left out once on trial and every point is judged
again at that fit; only if that fit still is not a clean cloud is nothing left out.

Drift checks
------------
Readings of a capture's drift checks (``set=drift``: one reference pose measured again
and again while the robot warms up) are a set of their own: each is the measurement of
the drift itself, so a reading out of line with a model that lacks the drift is the
signal the diagnosis needs, not a blunder. They stay in the fit and in the residuals, but
the test does not judge them (``exempt``): they are neither counted nor named, nor do
they widen the bulk's scale, and the verdict says how many were not tested. Their own
bound is the capture's (:mod:`daq.drift_checks`).

Direction
---------
When the measurement frame is the tracker's (the tracker at its origin; judged so when
no point lies closer than :data:`MIN_TRACKER_RANGE_MM` to it) the beam at a point runs
along its measured xyz; a residual within :data:`ALONG_BEAM_DEG` of that line is
``along_beam`` (a range error: a wrong return, a re-seated SMR), otherwise not
(an angular error or a moved target). Unknown (None) in a robot-base frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..numerics.chi3 import chi3_isf
from .leverage import residual_factors, residuals_on, studentised_norms
from .leverage import studentise as studentise

if TYPE_CHECKING:
    from ..data.dataset import Dataset
    from .identify import Fit

#: median and MAD of the chi distribution with 3 degrees of freedom
CHI3_MEDIAN = chi3_isf(0.5)  # chi(3).median()
CHI3_MAD = 0.46024377
#: significance of one false alarm in a clean Gaussian cloud (Bonferroni over the points)
ALPHA = 0.01
#: more points out of line than this fraction: not a few blunders, nothing is left out
MAX_FRACTION = 0.06
#: a residual within this angle of the line of sight is "along the beam"
ALONG_BEAM_DEG = 25.0
#: no tracker measures closer than this: a point nearer the origin means the measurement
#: frame is not the tracker's (e.g. data already in the robot base frame)
MIN_TRACKER_RANGE_MM = 500.0
#: refits of the exclusion loop before it stops
MAX_ROUNDS = 8
MODES = ("exclude", "flag", "keep")


@dataclass
class Blunder:
    """One measurement out of line with the rest."""

    pose_id: str
    index: int  # row in the calibration rows the test was given
    line: int  # line in the data file (0 when not from a file)
    residual_mm: float  # 3-D residual (excluded: distance from what the others predict)
    ratio: float  # residual over the out-of-line threshold (> 1)
    along_beam: bool | None  # None when the line of sight is unknown
    angle_deg: float | None  # angle between the residual and the line of sight

    def to_json(self, excluded: bool) -> dict:
        return {"pose_id": self.pose_id, "residual_mm": self.residual_mm,
                "along_beam": self.along_beam, "excluded": excluded, "line": self.line,
                "angle_to_beam_deg": self.angle_deg}

    def describe(self) -> str:
        """``p017 (2.41 mm, along the beam)``."""
        where = {True: ", along the beam", False: ", across the beam", None: ""}[self.along_beam]
        return f"{self.pose_id} ({self.residual_mm:.2f} mm{where})"


@dataclass
class BlunderScreen:
    """The result of :func:`find_blunders` (and, with the loop, of :func:`screen_fit`).

    Attributes
    ----------
    blunders : the points out of line, largest residual first (empty when the residuals
        are not a clean cloud: then nothing is named)
    n : number of points tested
    n_out_of_line : points beyond the threshold (> len(blunders) when not a clean cloud)
    scale : the bulk's robust scale in units of the instrument's uncertainty (>= 1 when
        the uncertainty is known)
    sigma_mm : the instrument's per-axis uncertainty (RMS over the points), None unknown
    threshold_mm : 3-D residual beyond which a point is out of line (at ``sigma_mm``)
    clean_cloud : False when too many points are out of line to be blunders
    mode : ``exclude`` (left out of the fit), ``flag`` (fitted, only named) or ``test``
    rounds : refits the exclusion loop took
    n_exempt : points not tested (a capture's drift-check readings); ``n`` excludes them
    """

    blunders: list[Blunder]
    n: int
    n_out_of_line: int
    scale: float
    sigma_mm: float | None
    threshold_mm: float
    clean_cloud: bool
    mode: str = "test"
    rounds: int = 0
    max_fraction: float = MAX_FRACTION
    notes: list[str] = field(default_factory=list)
    n_exempt: int = 0
    #: (n,) standardised residuals (in units of the instrument's uncertainty) and which of
    #: them are beyond the threshold
    u: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    beyond: np.ndarray = field(default_factory=lambda: np.zeros(0, bool), repr=False)

    @property
    def limit(self) -> int:
        """The most points that can be blunders (``max_fraction`` of them, at least one)."""
        return max(1, int(math.floor(self.max_fraction * self.n + 1e-9)))

    @property
    def excluded(self) -> bool:
        """Whether the blunders were left out of the fit."""
        return self.mode == "exclude" and bool(self.blunders)

    @property
    def ids(self) -> list[str]:
        return [b.pose_id for b in self.blunders]

    def to_json(self) -> list[dict]:
        """The ``outliers`` list of ``calibrate --json`` / ``diagnose --json`` (FORMATS §4)."""
        return [b.to_json(self.mode == "exclude") for b in self.blunders]

    def check_json(self, context: str = "fit") -> dict:
        """The ``outlier_check`` object: how the test was made and what it concluded."""
        return {"mode": self.mode, "n_tested": self.n, "n_out_of_line": self.n_out_of_line,
                "clean_cloud": self.clean_cloud, "threshold_mm": self.threshold_mm,
                "sigma_mm": self.sigma_mm, "scale": self.scale, "rounds": self.rounds,
                "message": self.message(context)}

    def message(self, context: str = "fit", list_points: bool = True) -> str:
        """The verdict in one or two sentences; ``context`` "fit" (calibrate) or "ranking"
        (diagnose) says what the blunders were left out of; ``list_points`` names them."""
        tail = self._exempt_sentence()
        if not self.clean_cloud:
            head = (f"{self.n_out_of_line} of {self.n} points lie beyond "
                    f"{self.threshold_mm:.3f} mm: the residuals are not a clean cloud with a "
                    f"few blunders, so none was left out")
            if context == "ranking":
                return head + " of the ranking." + tail
            return head + "; the model misses something (run `cellcal diagnose`)." + tail
        if not self.blunders:
            return (f"No measurement is out of line (threshold {self.threshold_mm:.3f} mm)."
                    + tail)
        k = len(self.blunders)
        what = "1 measurement looks like a blunder" if k == 1 else \
            f"{k} measurements look like blunders"
        it = "it is" if k == 1 else "they are"
        if self.mode == "flag":
            tail = f"{it} still in the fit (--outliers flag)"
        else:
            tail = f"{it} left out of the {'ranking' if context == 'ranking' else 'fit'}"
        points = ": " + ", ".join(b.describe() for b in self.blunders) if list_points else ""
        return f"{what} (beyond {self.threshold_mm:.3f} mm){points}; {tail}." + \
            self._exempt_sentence()

    def _exempt_sentence(self) -> str:
        if not self.n_exempt:
            return ""
        k = self.n_exempt
        return (f" The {k} drift-check reading{'s' if k > 1 else ''} {'are' if k > 1 else 'is'}"
                " not tested: each measures the drift itself.")


def _robust_scale(u: np.ndarray) -> float:
    """max(median / median(chi3), MAD / MAD(chi3)) of standardised 3-D residual norms."""
    med = float(np.median(u))
    mad = float(np.median(np.abs(u - med)))
    return max(med / CHI3_MEDIAN, mad / CHI3_MAD)


def threshold(n: int, alpha: float = ALPHA) -> float:
    """k: the chi(3) quantile at 1 - alpha / n."""
    return chi3_isf(alpha / max(n, 1))  # chi(3).isf


def line_of_sight_known(xyz: np.ndarray) -> bool:
    """Whether the measurement frame looks like the tracker's (no point too near it)."""
    xyz = np.atleast_2d(xyz)
    return bool(len(xyz)) and float(np.linalg.norm(xyz, axis=1).min()) >= MIN_TRACKER_RANGE_MM


def beam_angles(residuals: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Angle (deg, 0-90) between each residual and the line of sight along ``xyz``."""
    r = np.atleast_2d(residuals)
    b = np.atleast_2d(xyz)
    c = np.abs(np.sum(r * b, axis=1)) / np.maximum(
        np.linalg.norm(r, axis=1) * np.linalg.norm(b, axis=1), 1e-300)
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def point_sigmas(data: Dataset) -> tuple[np.ndarray | None, float | None]:
    """(per-point sigma (n,) or None, RMS sigma or None) of a :class:`Dataset`."""
    if data.sigma_mm is not None:
        return np.asarray(data.sigma_mm, float), data.sigma()
    s = data.sigma()
    return (None, None) if s is None else (np.full(data.n, s), s)


def find_blunders(
    fit_or_residuals: Fit | np.ndarray,
    sigma: float | np.ndarray | None = None,
    *,
    xyz: np.ndarray | None = None,
    pose_id: list[str] | None = None,
    lines: np.ndarray | None = None,
    alpha: float = ALPHA,
    max_fraction: float = MAX_FRACTION,
    named: np.ndarray | None = None,
    leverage: np.ndarray | None = None,
    exempt: np.ndarray | None = None,
) -> BlunderScreen:
    """Test residuals for blunders: points far out of line with a clean cloud.

    Parameters
    ----------
    fit_or_residuals : a :class:`~calibration.fit.identify.Fit` (its calibration residuals,
        points, ids and the instrument sigma of its data), or residuals, array (n, 3), mm
    sigma : the instrument's per-axis uncertainty, mm: a number, per point (n,), or None
        (unknown: no lower bound). With a Fit, default from its data.
    xyz : (n, 3) measured points, for the direction relative to the line of sight
    pose_id, lines : labels and file lines of the points (default 1..n, 0)
    alpha : chance of one false alarm in a clean Gaussian cloud
    max_fraction : more points than this fraction out of line: not a clean cloud
    named : (n,) bool, name these points instead of those out of line (the loop's final set)
    leverage : (n, 3, 3) each residual's covariance over sigma^2 (``I - H_ii``, see
        :func:`residual_factors`); default the identity (no studentisation). With a Fit,
        computed from it.
    exempt : (n,) bool, points not tested (never out of line, not in the scale nor in
        the count): a capture's drift-check readings. With a Fit, its data's drift rows.

    Returns
    -------
    BlunderScreen (``mode`` "test"); nothing is refitted.
    """
    if hasattr(fit_or_residuals, "residuals"):
        fit = cast("Fit", fit_or_residuals)
        d = fit.data
        residuals = fit.residuals
        xyz = d.tracker_p_smr if xyz is None else xyz
        pose_id = d.pose_id if pose_id is None else pose_id
        lines = d.lines if lines is None else lines
        if sigma is None:
            sigma = point_sigmas(d)[0]
        if leverage is None:
            leverage = residual_factors(fit, d, np.ones(d.n, bool))
        if exempt is None:
            exempt = d.drift_rows()
    else:
        residuals = fit_or_residuals
    r = np.atleast_2d(np.asarray(residuals, float))
    n = r.shape[0]
    e = np.linalg.norm(r, axis=1) if n else np.zeros(0)
    known = sigma is not None
    s = np.broadcast_to(np.asarray(sigma if known else 1.0, float), (n,))
    sigma_rms = float(np.sqrt(np.mean(s**2))) if known and n else None
    exempt = np.zeros(n, bool) if exempt is None else np.asarray(exempt, bool)
    tested = ~exempt
    n_tested = int(tested.sum())
    if n_tested == 0:
        return BlunderScreen([], 0, 0, 1.0, sigma_rms, math.inf, True, n_exempt=n - n_tested)
    u = (e if leverage is None else studentised_norms(r, leverage)) / s
    scale = _robust_scale(u[tested])
    if known:
        scale = max(scale, 1.0)
    scale = max(scale, 1e-9 / float(np.mean(s)))  # noise-free synthetic data
    k = threshold(n_tested, alpha)
    beyond = (u > k * scale) & tested
    thr_mm = k * scale * (sigma_rms if sigma_rms is not None else 1.0)  # known, n > 0
    limit = max(1, int(math.floor(max_fraction * n_tested + 1e-9)))
    clean = int(beyond.sum()) <= limit
    out = np.flatnonzero(beyond if named is None else named) if clean else np.zeros(0, int)
    ids = pose_id if pose_id is not None else [str(i + 1) for i in range(n)]
    ln = np.zeros(n, int) if lines is None else np.asarray(lines)
    angles = beam_angles(r, xyz) if xyz is not None and line_of_sight_known(xyz) else None
    blunders = []
    for i in out[np.argsort(-u[out])]:
        ang = None if angles is None else float(angles[i])
        blunders.append(Blunder(
            pose_id=str(ids[i]), index=int(i), line=int(ln[i]), residual_mm=float(e[i]),
            ratio=float(u[i] / (k * scale)),
            along_beam=None if ang is None else bool(ang <= ALONG_BEAM_DEG), angle_deg=ang))
    return BlunderScreen(blunders, n_tested, int(beyond.sum()), float(scale), sigma_rms,
                         float(thr_mm), clean, max_fraction=max_fraction, u=u, beyond=beyond,
                         n_exempt=n - n_tested)


def screen_fit(fit: Fit, mode: str, refit: Callable[[Dataset, np.ndarray], Fit],
               **test_kw: Any) -> Fit:
    """Find the blunders of ``fit`` by the exclusion loop (see the module docstring).

    Parameters
    ----------
    fit : a :class:`~calibration.fit.identify.Fit` of every calibration point
    mode : ``exclude`` (return the fit without the blunders), ``flag`` (return ``fit``
        itself, the blunders only named) or ``keep`` (return ``fit`` untested)
    refit : ``refit(calib_rows, x0) -> Fit``: the same identification of a subset of the
        calibration rows, warm-started at ``x0``, without its own screening
    test_kw : passed to :func:`find_blunders`

    Returns
    -------
    Fit with ``outliers`` set to the :class:`BlunderScreen`.
    """
    if mode not in MODES:
        raise ValueError(f"outliers must be one of {', '.join(MODES)}, not {mode!r}")
    if mode == "keep":
        return fit
    full = fit.data
    sig = point_sigmas(full)[0]
    kw: dict[str, Any] = {"xyz": full.tracker_p_smr, "pose_id": full.pose_id,
                          "lines": full.lines, "exempt": full.drift_rows(), **test_kw}
    out = np.zeros(full.n, bool)
    seen = {out.tobytes()}
    current, rounds, settled, trial = fit, 0, True, False
    while True:
        resid, J = residuals_on(current, full, out)
        kw["leverage"] = residual_factors(current, full, ~out, J)
        screen = find_blunders(resid, sig, **kw)
        if screen.clean_cloud:
            new = screen.beyond.copy()
        elif not out.any() and not trial:
            # large blunders drag a least-squares fit (a flexible one most) until many
            # points look out of line: leave the worst few per cent out once, and judge
            # every point again at that fit
            trial = True
            new = np.zeros(full.n, bool)
            new[np.argsort(-np.where(kw["exempt"], -np.inf, screen.u))[: screen.limit]] = True
        else:
            current, out = fit, np.zeros(full.n, bool)
            break
        if (new == out).all():
            break
        if new.tobytes() in seen or rounds == MAX_ROUNDS:
            settled = False
            break
        seen.add(new.tobytes())
        out = new
        current = refit(full.subset(~out), current.values) if out.any() else fit
        rounds += 1
    if screen.clean_cloud and not np.array_equal(screen.beyond, out):
        # name exactly the points left out of ``current`` (when the loop settled, the
        # points out of line are those: the test as it stands names them)
        screen = find_blunders(resid, sig, named=out, **kw)
    if not settled:
        screen.notes.append("the exclusion loop did not settle; its last set is used")
    screen.rounds, screen.mode = rounds, mode
    result = current if mode == "exclude" else fit
    result.outliers = screen
    return result



def concentration(r: np.ndarray, d: np.ndarray, n: int, k: int = 2) -> float:
    """Share of a candidate's explained sum of squares that its ``k`` largest points carry.

    ``r`` (3 n,) the residual, ``d`` (3 n,) its projection on the candidate (the fitted
    correction); point i contributes ``r_i . d_i`` (they sum to ``|d|^2``). Near 1: the
    candidate explains one or two points, not an effect.
    """
    return concentration_of(np.sum((r * d).reshape(n, 3), axis=1), k)


def concentration_of(c: np.ndarray, k: int = 2) -> float:
    """:func:`concentration` from each point's contribution ``c`` (n,)."""
    total = float(c.sum())
    if total <= 0:
        return 0.0
    top = np.partition(c, c.size - k)[c.size - k :] if c.size > k else c  # O(n), no sort
    return float(np.sort(top)[::-1].sum() / total)
