"""The staged fit behind ``cellcal report``, ``cellcal diagnose`` and ``cellcal demo``.

The story of a calibration in three fits: the *uncalibrated* robot (nominal kinematics,
only where it stands and where the SMR sits fitted), the *current* model (its parameters
read from a params.json, or identified) and, when the diagnosis of the current model
finds a significant missing effect, the current model *plus that effect*, refitted.

With ``auto`` the third act is the automatic diagnosis instead
(:func:`~calibration.diagnosis.auto_diagnosis.auto_diagnose`): effects added one at a time while the
held-out error falls, every step kept as an :class:`AutoStory` (the fit after each step, its
calibration and held-out RMS). A params.json written by ``diagnose --auto --out`` records its
steps (``auto_steps``); given such a file, the steps are replayed (each prefix of the
effects refitted) so that the report shows them too.

:func:`joint_view` gives a fit's residual on any rows as seen from each joint, and the
lever arm that view has (what a report plots against the joint's angle or torque).

Numbers only: the callers label the stages, print and render them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .data.dataset import Dataset
from .diagnosis.auto_diagnosis import AutoDiagnosis, auto_diagnose, explain_effect, heldout_errors
from .diagnosis.diagnosis import Diagnosis, diagnose
from .effects import DEFAULT_EFFECTS
from .exports.params_io import ParamsError, read_auto_steps, read_params
from .fit.envelope import identify_supported
from .fit.error_model import ErrorModel
from .fit.full_pose import for_data
from .fit.identify import Fit, fit_at, identify
from .model.robot_model import RobotModel

#: the "uncalibrated" reference: nominal kinematics, with only the base (where the robot
#: stands) and the tool (where the SMR sits) fitted, since neither is a property of the arm
UNCALIBRATED_EFFECTS = "base,tool"
UNCALIBRATED_LABEL = "uncalibrated (best-fit base and tool)"

#: where the current model's parameters come from: a params.json path, or
#: (error model, values in internal units)
ParamsSource = str | Path | tuple[ErrorModel, np.ndarray]


def fit_uncalibrated(model: RobotModel, data: Dataset, **kw: Any) -> Fit:
    """The nominal robot's accuracy: only the base and tool fitted (see
    :data:`UNCALIBRATED_EFFECTS`); ``kw`` go to :func:`~calibration.fit.identify.identify`."""
    em, _ = for_data(ErrorModel(model, UNCALIBRATED_EFFECTS), data, position_only=True)
    return identify(em, data, **kw)


def current_fit(model: RobotModel, data: Dataset, effects: str = DEFAULT_EFFECTS,
                params: ParamsSource | None = None, solver: str = "lm") -> Fit:
    """The current model's fit: at given parameters, else identified.

    Parameters
    ----------
    model : the nominal robot of the data
    data : the measured poses (calibration and ``set=valid`` rows)
    effects : the current model's effects (ignored with ``params``)
    params : the current model's parameters are taken from there instead of fitted
        (:func:`~calibration.fit.identify.fit_at`), see :data:`ParamsSource`
    solver : identification method

    Raises :class:`~calibration.exports.params_io.ParamsError` when the parameters' model has
    other joints or another convention than ``model``; the loaders' own errors pass
    through.
    """
    if params is None:
        fit, notes = identify_supported(ErrorModel(model, effects), data, solver)
        fit.notes.extend(notes)
        return fit
    notes = []
    if isinstance(params, (str, Path)):
        loaded = read_params(params, model=model)
        em, x, notes = loaded.error_model, loaded.values, loaded.notes
    else:
        em, x = params
        if em.model.n_joints != model.n_joints:
            raise ParamsError(f"parameters of a model with {em.model.n_joints} joints, "
                              f"the data's {model.name} has {model.n_joints}")
    fit = fit_at(em, data, x)
    fit.notes.extend(notes)
    return fit


@dataclass
class StagedFit:
    """The three fits of :func:`staged_fit` and the diagnosis that links them.

    Attributes
    ----------
    uncalibrated : nominal kinematics, base and tool fitted
    current : the current model (``given``: at the parameters of a params file)
    diagnosis : the diagnosis of ``current``
    improved : ``current`` plus the recommended effect, refitted; None when nothing
        significant is missing (or not asked for, or with ``story``)
    given : the current parameters were given, not fitted
    timings : seconds spent fitting (``fit_s``) and diagnosing (``diagnose_s``; with the
        automatic diagnosis also ``auto_s``)
    story : the automatic diagnosis' steps (run, or replayed from a params.json that
        recorded them), else None; ``diagnosis`` is then that of its final model
    """

    uncalibrated: Fit
    current: Fit
    diagnosis: Diagnosis
    improved: Fit | None = None
    given: bool = False
    timings: dict[str, float] = field(default_factory=dict)
    story: AutoStory | None = None

    @property
    def added_effect(self) -> str | None:
        """The effect ``improved`` adds to the current model, or None."""
        best = self.diagnosis.best  # the effect ``improved`` was fitted with
        return None if self.improved is None or best is None else best.effect


def staged_fit(data: Dataset, model: RobotModel, effects: str = DEFAULT_EFFECTS,
               params: ParamsSource | None = None, *, solver: str = "lm",
               refit: bool = True, auto: bool = False, max_steps: int = 12,
               budget_s: float | None = None) -> StagedFit:
    """Uncalibrated → current → current plus the recommended effect (or, with ``auto``,
    the automatic diagnosis' steps).

    Parameters are those of :func:`current_fit`; ``refit`` adds the recommended effect
    (when the diagnosis finds a significant one) and refits, with the same solver.
    ``auto`` runs :func:`~calibration.diagnosis.auto_diagnosis.auto_diagnose` from the current model
    (``max_steps``, ``budget_s`` as there) and diagnoses its final model. Without
    ``auto``, a params.json that recorded the automatic diagnosis' steps (``auto_steps``)
    has them replayed (:func:`replay_story`).
    """
    t0 = time.perf_counter()
    current = current_fit(model, data, effects, params, solver)
    uncalibrated = fit_uncalibrated(model, data, solver=solver)
    t1 = time.perf_counter()
    story, timings = None, {}
    if auto:
        result = auto_diagnose(current, data, max_steps=max_steps, budget_s=budget_s)
        story = AutoStory.from_auto(result, uncalibrated)
        timings["auto_s"] = result.total_s
    elif isinstance(params, (str, Path)):
        record = read_auto_steps(params)
        if record is not None:
            story = replay_story(current, uncalibrated, data, record)
    t2 = time.perf_counter()
    diag = diagnose(story.final.fit if story is not None else current, data)
    t3 = time.perf_counter()
    improved = None
    if refit and story is None and diag.best is not None:
        improved = identify(current.error_model.with_effects(diag.best.effect), data, solver)
    t4 = time.perf_counter()
    timings = {"fit_s": t1 - t0 + t4 - t3 + (t2 - t1 if not auto else 0.0),
               "diagnose_s": t3 - t2, **timings}
    return StagedFit(uncalibrated, current, diag, improved, params is not None, timings,
                     story)


# ---- the automatic diagnosis as a story ---------------------------------------------------
@dataclass
class StoryStep:
    """One model of the automatic diagnosis' story: the start, or the model after a step.

    Attributes
    ----------
    effect : the effect this step added (None for the start)
    fit : the fit after the step
    heldout_rms_mm : held-out RMS (validation rows, else cross-validation), mm
    n_params : parameters the step added (the start: all of its model's)
    seconds : time the step took (None when not known)
    explanation : one line of physics for the effect
    blocked_rms_mm : RMS of the range-blocked folds (the poses at either end of each
        joint's range, predicted by the model refitted without them), mm
    """

    effect: str | None
    fit: Fit
    heldout_rms_mm: float | None
    n_params: int
    seconds: float | None = None
    explanation: str = ""
    #: the range-blocked folds' RMS (mm), None without them
    blocked_rms_mm: float | None = None

    @property
    def calib_rms_mm(self) -> float:
        return float(self.fit.calib["rms_mm"])


@dataclass
class AutoStory:
    """The steps of an automatic diagnosis, start first (``steps[0]``).

    Attributes
    ----------
    steps : the start model, then the model after every accepted step
    heldout_method : how the held-out error was measured
    stop_reason : why the loop stopped
    uncalibrated_heldout_rms_mm : the uncalibrated fit's held-out RMS, the same way
    recorded : the steps were replayed from a params.json's ``auto_steps`` (refitted on
        these data), not run here
    notes : what a replay could not use
    """

    steps: list[StoryStep]
    heldout_method: str
    stop_reason: str
    uncalibrated_heldout_rms_mm: float | None = None
    recorded: bool = False
    notes: list[str] = field(default_factory=list)

    @property
    def start(self) -> StoryStep:
        return self.steps[0]

    @property
    def final(self) -> StoryStep:
        return self.steps[-1]

    @property
    def added(self) -> list[StoryStep]:
        """The accepted steps (without the start)."""
        return self.steps[1:]

    @classmethod
    def from_auto(cls, result: AutoDiagnosis, uncalibrated: Fit) -> AutoStory:
        start = result.start
        steps = [StoryStep(None, start, result.start_heldout_rms_mm,
                           start.error_model.n_params,
                           blocked_rms_mm=result.start_blocked_rms_mm)]
        for s in result.steps:
            if s.fit is None:
                raise ValueError(f"auto step {s.effect}: no fit (a recorded step, not a run)")
            steps.append(StoryStep(s.effect, s.fit, s.heldout_rms_mm, s.n_params, s.seconds,
                                   s.explanation, s.blocked_rms_mm))
        return cls(steps, result.heldout_method, result.stop_reason,
                   heldout_errors(uncalibrated).rms_mm, notes=list(result.notes))


def replay_story(final: Fit, uncalibrated: Fit, data: Dataset, record: dict) -> AutoStory | None:
    """The recorded automatic diagnosis (``auto_steps`` of a params.json) on ``data``.

    ``final`` is the fit at the file's parameters; the start model and every intermediate
    one are refitted on ``data`` with the file's own effects (a table keeps its knots and
    smoothing), the last step is ``final`` itself. Held-out errors are measured as the
    automatic diagnosis measures them. None when the record does not match the file's
    effects (start effects followed by the steps').
    """
    em = final.error_model
    labels = list(em.labels)
    start_labels = list(record.get("start_effects", []))
    rec_steps = list(record.get("steps", []))
    if start_labels + [s.get("effect") for s in rec_steps] != labels or not rec_steps:
        return None
    steps = []
    for k in range(len(rec_steps) + 1):
        keep = labels[: len(start_labels) + k]
        if k == len(rec_steps):
            fit = final
        else:
            sub = ErrorModel(em.model, [e for e in em.effects if e.label in keep])
            fit = identify(sub, data, final.solver)
        ho = heldout_errors(fit)
        held = ho.rms_mm
        if k == 0:
            steps.append(StoryStep(None, fit, held, fit.error_model.n_params,
                                   blocked_rms_mm=ho.blocked_rms_mm))
            continue
        rs = rec_steps[k - 1]
        steps.append(StoryStep(
            rs["effect"], fit, held, int(rs.get("n_params", 0)), rs.get("seconds"),
            rs.get("explanation") or explain_effect(rs["effect"], em.model),
            ho.blocked_rms_mm))
    return AutoStory(steps, heldout_errors(final).method,
                     str(record.get("stop_reason", "")), heldout_errors(uncalibrated).rms_mm,
                     recorded=True)


# ---- the residual seen from each joint ---------------------------------------------------------
@dataclass
class JointView:
    """A fit's residuals on some rows as seen from each joint.

    Attributes
    ----------
    residuals : (n, 3) measured minus predicted, mm
    joint_residual_rad : (n, N) the correction of joint j alone that would explain each
        residual best (least squares along dP/dq_j), rad
    lever_arm_mm : (n, N) |dP/dq_j|: how far the target moves per radian of joint j (mm).
        Where it is short (the target near the joint's axis) the joint-equivalent residual
        is a large number that means nothing
    dP_dq : (n, 3, N) the columns the equivalents are taken along
    """

    residuals: np.ndarray
    joint_residual_rad: np.ndarray
    lever_arm_mm: np.ndarray
    dP_dq: np.ndarray

    def project(self, d: np.ndarray) -> np.ndarray:
        """Joint-equivalent corrections (n, N) rad of displacements ``d`` (n, 3) mm: the same
        projection as the residual's (a model change seen on the same basis)."""
        G = self.dP_dq
        g2 = np.einsum("nij,nij->nj", G, G)
        return np.einsum("nij,ni->nj", G, d) / np.where(g2 > 1e-12, g2, np.inf)


def joint_view(fit: Fit, rows: Dataset | None = None) -> JointView:
    """``fit``'s residual on ``rows`` (default its calibration rows) seen from each joint."""
    rows = fit.data if rows is None else rows
    em = fit.error_model
    P, _, G = em.evaluate(fit.values, em.bind(rows), jacobian=True, joints=True)
    r = rows.tracker_p_smr - P
    g2 = np.einsum("nij,nij->nj", G, G)
    jr = np.einsum("nij,ni->nj", G, r) / np.where(g2 > 1e-12, g2, np.inf)
    return JointView(r, jr, np.sqrt(g2), G)
