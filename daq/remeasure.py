"""Suspect readings re-measured at the cell, while the robot is still there.

A laser tracker's blunders (0.5-5 mm off: a wrong return, a re-seated SMR, someone in
the beam) leave nothing in the tracker's own statistics: the averaged reading's std is
as small as any other's (that check, ``max_std_mm``, is the executor's). They show only
against the robot: the reading is far from where the model fitted so far puts the
point. :class:`Remeasure` is the capture service's policy, not a routine's (the policy
at the cell: docs/capture.md, "Blunders: re-measured at the cell"); the executor hands
it each new sample before the commit (:meth:`Remeasure.settle`).

The running model (:class:`RunningModel`)
    ``geometric,base,tool`` of the run's nominal model (its controller tool),
    identified (:func:`calibration.fit.identify`) from the accepted calibration rows once
    there are :data:`WARMUP_FACTOR` times as many as the plan's calibration poses
    identify parameters; refitted, warm-started, every ``refit_every`` accepted
    calibration rows (or 10 % of them, when more), and used as it is in between. The
    solver is the robust one (``ridge`` with IGG3 pose weights, no ridge: a blunder
    gets no weight however many the warm-up holds; least squares with the blunder
    screen could not leave out more than 6 %, and four blunders in the 50 warm-up
    rows of a UR10e at a 5 % rate are not rare), on one BLAS thread (small systems).
    A new reading (calibration or validation row) is judged by the test of
    :func:`calibration.fit.outliers.find_blunders`: its residual from the
    prediction, studentised with the prediction's covariance (``I + H``), over the
    tracker's sigma of the reading (the RMS of its per-axis std) is out of line when
    it exceeds ``k c``: ``k`` the chi(3) quantile at ``1 - alpha / n`` over the plan's
    ``n`` points, ``c`` the running fit's robust scale of the bulk (at least 1: the
    tracker's sigma is the floor).

Re-measuring a suspect
    The robot moves away and back: to the target's pre-position when the plan has one
    (the approach is the plan's own), else a retract of ``retract_rad`` on every
    joint against its approach direction (clipped to the model's joint limits; shortened
    so that the nominal tool point moves at most :data:`RETRACT_TOOL_MM`), then
    to the target again (a linear target without a pre-position: by a joint move to
    the joints read at the suspect reading, since a linear move to the same position
    may end in another wrist posture), both through the executor's own moves (checked
    by the run's motion guard before they are sent, the joints read back after; the
    retract and that joint move are adaptive: near the point's planned posture); the
    tracker measures again as at any point (the dwell, a quality-checked measurement
    newer than the previous one, the joints unchanged during it: :mod:`daq.executor`).
    Up to ``n`` times:

    * a re-measurement within the model's threshold is accepted (verdict
      ``remeasured``); the suspect reading is kept as rejected;
    * a re-measurement that agrees with an earlier reading (their difference within
      ``k c`` of their combined sigma) but not with the model is accepted: the model,
      not the reading, is off there (verdict ``model``);
    * after ``n`` re-measurements that agree with nothing, none is accepted: the
      point's sample keeps the reading closest to the model (so the run has one row
      per point and resumes as any other) with the verdict ``unresolved``, which
      ``cellcal export`` leaves out (a rejected reading with ``--all-readings``) and
      the running model does not take. Nothing would screen such a validation row.

Warm-up
    Readings taken before the first fit are not judged then (verdict ``warmup``). Once
    the model exists, every warm-up reading is judged as a new one would be, and
    those out of line are revisited: moved to again (from wherever the robot is; the
    approach directions are recorded as they are; a linear point with a pre-position by
    the executor's entry move first) and re-measured by the same rules,
    while the next point is being done; the new reading replaces the stored one in
    that point's commit. Validation rows have no other screen; a warm-up calibration
    row no revisit catches is left out by the calibration's screen. Revisits need a
    next point: a warm-up that ends with the plan revisits nothing.

Every reading that was not accepted goes to the store's ``readings`` table with its
reason, in the same transaction as the point's sample (a point killed mid-re-measure
has nothing stored and is done again on resume); the sample records the verdict, the
number of re-measurements and its distance from the model.

Log (``daq.remeasure``, INFO): the running model fitted and refitted, each suspect and
why, each re-measurement's verdict, the warm-up points to revisit, a model no longer
trusted to call blunders.

Units: mm, rad, s.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np
from threadpoolctl import threadpool_limits

from calibration import Dataset, ErrorModel, identify
from calibration.fit.outliers import ALPHA, residual_factors, studentise, threshold
from calibration.model.kinematics import tool_points

from .executor import PointContext, approach_dirs
from .plans import Plan, Target
from .store import Reading, RunStore, Sample

log = logging.getLogger(__name__)

#: the running model's effects
EFFECTS = "geometric,base,tool"
#: the running model is fitted once the accepted calibration rows are this many times
#: the parameters the plan's calibration poses identify
WARMUP_FACTOR = 2
#: a retract moves the nominal tool point about this far at most (mm; scaled to first
#: order), within the motion guard's 25 mm for an adaptive move (``max_dev_mm``): 0.01 rad
#: a joint moves a UR10e's tool up to 25 mm and an IRB 2600's (1.65 m) up to 31 mm, so a
#: long arm's retract is shortened (the same direction) instead of refused
RETRACT_TOOL_MM = 20.0
#: the running model's solver options: IGG3 weights without a ridge (robust, no shrinkage)
SOLVER_OPTIONS = {"ridge": {"xi": 0.0}}
#: how each accepted reading was judged (samples' ``verdict``), and the note ``cellcal
#: export --all-readings`` writes for it
VERDICTS = {
    "warmup": "",
    "ok": "",
    "remeasured": "re-measured: agrees with the model",
    "model": "re-measurements agree with each other, not with the model: the model is off",
    "unresolved": "unresolved: no two readings agree, none with the model (the one "
                  "closest to the model kept in the store, left out of the export)",
}


@dataclass(frozen=True)
class Judgement:
    """A reading against the running model: ``suspect`` None when there is no model yet;
    ``residual_mm`` its 3-D distance from the prediction, ``threshold_mm`` the limit at
    its sigma, ``ratio`` its studentised residual over the limit (> 1: suspect)."""

    suspect: bool | None
    residual_mm: float | None = None
    threshold_mm: float | None = None
    ratio: float | None = None

    def describe(self) -> str:
        return (f"{self.residual_mm:.3f} mm from the running model (threshold "
                f"{self.threshold_mm:.3f} mm)")


def reading_sigma(s: Sample) -> float:
    """The tracker's per-axis sigma of a reading: the RMS of its per-axis std (mm)."""
    return max(float(np.sqrt(np.mean(np.square(s.std_mm)))), 1e-9)


def identifiable_count(error_model: ErrorModel, q: np.ndarray) -> int:
    """How many parameters of ``error_model`` poses ``q`` (rad, (n, N)) identify
    (structural: at the nominal geometry, as :func:`calibration.fit.identify` judges it)."""
    if len(q) < 2:
        return error_model.n_params
    data = Dataset(q=q, tracker_p_smr=tool_points(error_model.model, q))
    fit = identify(error_model, data, solver_options={"max_iter": 0}, outliers="keep")
    return int(fit.free.sum())


class RunningModel:
    """The model fitted so far to a run's accepted readings (module docstring).

    Parameters
    ----------
    model : RobotModel, the run's nominal model with the controller's tool
    plan : Plan, the run's plan (its calibration poses set the warm-up, its size ``k``)
    refit_every : refit after this many new accepted calibration rows (at least)
    alpha : chance of one false suspect in a run at the noise floor
    solver : the running fit's solver (``ridge``, with :data:`SOLVER_OPTIONS`: robust)
    """

    def __init__(self, model, plan: Plan, *, refit_every: int = 10,
                 alpha: float = ALPHA, solver: str = "ridge") -> None:
        self.solver = solver
        self.error_model = ErrorModel(model, EFFECTS)
        calib_q = np.array([t.q for t in plan.targets if t.set == "calib" and t.q is not None])
        self.n_identifiable = identifiable_count(self.error_model, calib_q)
        self.min_points = WARMUP_FACTOR * self.n_identifiable
        self.k = threshold(len(plan), alpha)
        self.refit_every = max(1, int(refit_every))
        #: every accepted reading by point index (calibration and validation rows)
        self.samples: dict[int, Sample] = {}
        self.fit = None
        self.n_fitted = 0
        #: (calibration rows, seconds) of every refit in this session
        self.refits: list[tuple[int, float]] = []

    # ---------------------------------------------------------------- data
    def _calib(self) -> list[Sample]:
        return [s for s in self.samples.values() if s.set_name == "calib"]

    def add(self, s: Sample) -> bool:
        """Take a point's reading (a new point's, or one replacing a point's; an
        unresolved one is left out); refit when due. Returns True when this made the
        first fit of the session."""
        if s.verdict == "unresolved":
            self.samples.pop(int(s.point_index), None)
            return False
        self.samples[int(s.point_index)] = s
        first = self.fit is None
        n = len(self._calib())
        if n < self.min_points:
            return False
        if first or n - self.n_fitted >= max(self.refit_every, self.n_fitted // 10):
            self.refit()
        return first and self.fit is not None

    def refit(self) -> None:
        rows = self._calib()
        data = Dataset(q=np.array([s.q for s in rows]),
                       tracker_p_smr=np.array([s.tracker_p_smr for s in rows]),
                       pose_id=[str(s.point_index) for s in rows],
                       sigma_mm=np.array([reading_sigma(s) for s in rows]))
        t0 = time.perf_counter()
        try:
            with threadpool_limits(limits=1, user_api="blas"):  # small systems: one thread
                fit = identify(self.error_model, data, self.solver,
                               x0=None if self.fit is None else self.fit.values,
                               solver_options=SOLVER_OPTIONS.get(self.solver))
        except (ValueError, np.linalg.LinAlgError) as e:  # no model this time: keep the last
            log.info("running model: the refit on %d rows failed (%s): the last one is kept",
                     data.n, e)
            fit = self.fit
        self.refits.append((data.n, time.perf_counter() - t0))
        first = self.fit is None
        self.fit, self.n_fitted = fit, data.n
        if fit is not None:
            log.info("running model %s on %d calibration rows in %.2f s (scale %.2f)",
                     "fitted" if first else "refitted", data.n, self.refits[-1][1], self.scale)

    @property
    def scale(self) -> float:
        """The running fit's robust scale of the bulk, in tracker sigmas (>= 1)."""
        o = None if self.fit is None else self.fit.outliers
        return 1.0 if o is None else max(float(o.scale), 1.0)

    # -------------------------------------------------------------- judging
    def judge(self, s: Sample) -> Judgement:
        """A reading against the prediction of the running model."""
        if self.fit is None:
            return Judgement(None)
        row = Dataset(q=np.asarray(s.q, float)[None],
                      tracker_p_smr=np.asarray(s.tracker_p_smr, float)[None])
        r = row.tracker_p_smr - self.fit.predict(row)
        M = residual_factors(self.fit, row, np.zeros(1, bool))
        sig = reading_sigma(s)
        u = float(np.linalg.norm(studentise(r, M))) / sig
        limit = self.k * self.scale
        return Judgement(bool(u > limit), float(np.linalg.norm(r)), limit * sig, u / limit)

    def agree(self, a: Sample, b: Sample) -> bool:
        """Whether two readings of a point agree (within ``k c`` of their combined sigma)."""
        d = float(np.linalg.norm(np.asarray(a.tracker_p_smr) - np.asarray(b.tracker_p_smr)))
        return d <= self.k * self.scale * float(np.hypot(reading_sigma(a), reading_sigma(b)))

    def warmup_suspects(self) -> list[int]:
        """Point indices of the warm-up readings out of line with the fit (judged as a new
        reading would be: a blunder has no weight in the robust fit)."""
        return [p for p, s in sorted(self.samples.items())
                if s.verdict == "warmup" and self.judge(s).suspect]


@dataclass
class Settled:
    """What :meth:`Remeasure.settle` decided for a point: the accepted ``sample``, the
    point's ``rejected`` readings and the warm-up points ``revisited`` meanwhile
    (``(sample, rejected)`` pairs); all written in the point's commit."""

    sample: Sample
    rejected: list[Reading] = field(default_factory=list)
    revisited: list[tuple[Sample, list[Reading]]] = field(default_factory=list)


#: the share of judged readings confirmed against the model above which the model is taken
#: to be incomplete and no longer trusted to call blunders (see Remeasure.model_trusted)
MODEL_OFF_FRACTION = 0.05


class Remeasure:
    """The re-measure policy of a run (module docstring).

    Parameters
    ----------
    running : RunningModel
    plan : Plan
    n : re-measurements of a suspect point (at least 1)
    retract_rad : the retract away from a target without a pre-position (rad per joint)
    limits : (N, 2) joint limits (rad) the retract stays within
    deadband_rad : a joint moved less than this approached with direction 0
    model : the robot model whose nominal tool point a retract moves at most
        :data:`RETRACT_TOOL_MM` (None: the retract as given)
    """

    def __init__(self, running: RunningModel, plan: Plan, *, n: int, retract_rad: float,
                 limits: np.ndarray, deadband_rad: float = 1e-6, model=None) -> None:
        self.running, self.n = running, max(1, int(n))
        self.model = model
        self.targets = {t.index: t for t in plan.targets}
        self.retract_rad, self.limits = float(retract_rad), np.asarray(limits, float)
        self.deadband_rad = float(deadband_rad)
        self.pending: list[int] = []
        #: readings judged against the model, and re-measurements that agreed with each
        #: other but not with it (the model, not the reading, was off)
        self.judged = 0
        self.model_off = 0

    def model_trusted(self) -> bool:
        """Whether the running model still tells blunders from physics: once more than a
        few per cent of the judged readings were confirmed by their re-measurement against
        it (an effect the model lacks, e.g. backlash — a case for ``diagnose``), a reading
        out of line with it is no longer re-measured on its word."""
        return self.model_off <= max(3, MODEL_OFF_FRACTION * self.judged)

    @classmethod
    def for_run(cls, store: RunStore, run_id: int, plan: Plan, model, options
                ) -> Remeasure | None:
        """The policy of a run with ``options`` (:class:`~daq.run_context.ExecutorOptions`),
        its running model built from the readings already stored (a resumed run); None
        when ``options.remeasure`` is 0."""
        if options.remeasure <= 0:
            return None
        running = RunningModel(model, plan, refit_every=options.remeasure_refit_every)
        policy = cls(running, plan, n=options.remeasure, retract_rad=options.remeasure_retract_rad,
                     limits=model.limits_rad(), deadband_rad=options.dir_deadband_rad,
                     model=model)
        stored = store.samples(run_id)
        for i in range(len(stored)):
            if stored.verdict[i] != "unresolved":
                running.samples[int(stored.point_index[i])] = stored.sample(i)
        if len(running._calib()) >= running.min_points:
            running.refit()
            policy.pending = running.warmup_suspects()
        return policy

    # ------------------------------------------------------------ the policy
    def settle(self, t: Target, sample: Sample, ctx: PointContext) -> Settled:
        """Judge ``t``'s new reading and re-measure it when it is suspect (the robot is
        still at ``t``); then revisit the pending warm-up suspects."""
        if t.move == "zero":
            return Settled(sample)
        out = Settled(*self._resolve(t, sample, ctx, revisit=False))
        for p in list(self.pending):
            old = self.running.samples.get(p)
            new, rejected = (old, []) if old is None else self._resolve(
                self.targets[p], old, ctx, revisit=True)
            if rejected or new.remeasures != old.remeasures:
                out.revisited.append((new, rejected))
            else:  # no longer out of line (a later fit), nothing measured
                self.pending.remove(p)
        return out

    def committed(self, settled: Settled) -> None:
        """The point's commit landed: the running model takes its readings."""
        for new, _ in settled.revisited:
            self.running.add(new)
            self.pending = [p for p in self.pending if p != new.point_index]
        if self.running.add(settled.sample):
            self.pending = self.running.warmup_suspects()
            if self.pending:
                log.info("warm-up readings out of line with the running model, revisited "
                         "while the next points are done: points %s", self.pending)

    def _resolve(self, t: Target, first: Sample, ctx: PointContext, *, revisit: bool
                 ) -> tuple[Sample, list[Reading]]:
        """The accepted reading of ``t`` and its rejected ones, from ``first`` on."""
        j = self.running.judge(first)
        if j.suspect is None:
            return replace(first, verdict="warmup"), []
        first = _with_model(first, j, first.verdict if revisit else "ok")
        self.judged += 1
        if not j.suspect:
            return first, []
        if not self.model_trusted():
            log.info("point %d (%s): %s, not re-measured: the running model is no longer "
                     "trusted (%d of %d judged readings confirmed against it)", t.index,
                     t.label, j.describe(), self.model_off, self.judged)
            return first, []
        note = "warm-up reading, judged once the model was fitted: " if revisit else ""
        log.info("point %d (%s): %s%s: re-measuring (up to %d times)", t.index, t.label,
                 "revisited, " if revisit else "", j.describe(), self.n)
        readings = [(first, j, note + j.describe())]
        for k in range(1, self.n + 1):
            s = self._again(t, first, ctx, approach=revisit and k == 1)
            jk = self.running.judge(s)
            s = _with_model(s, jk, "remeasured", k)
            if not jk.suspect:
                log.info("point %d (%s): re-measurement %d agrees with the model (%s): "
                         "accepted, %d reading(s) rejected", t.index, t.label, k,
                         jk.describe(), len(readings))
                return s, [Reading(r, f"{why}; a re-measurement agrees with the model")
                           for r, _, why in readings]
            same = [self.running.agree(r, s) for r, _, _ in readings]
            if any(same):
                self.model_off += 1
                log.info("point %d (%s): re-measurement %d agrees with an earlier reading, "
                         "not with the model (%s): the model, not the reading, is off there",
                         t.index, t.label, k, jk.describe())
                return replace(s, verdict="model"), [Reading(r, f"{why}; " + (
                    "agrees with the accepted re-measurement (the model, not the reading, is "
                    "off)" if agrees else "agrees with no other reading"))
                    for (r, _, why), agrees in zip(readings, same, strict=True)]
            readings.append((s, jk, "re-measurement: " + jk.describe()))
        best = min(range(len(readings)), key=lambda i: readings[i][1].ratio)
        log.info("point %d (%s): unresolved after %d re-measurements (no two readings agree, "
                 "none with the model): the closest kept, left out of the export", t.index,
                 t.label, self.n)
        kept = replace(readings[best][0], verdict="unresolved", remeasures=self.n)
        return kept, [Reading(r, f"{why}; no two readings agree: the one closest to the model "
                                 "was kept") for i, (r, _, why) in enumerate(readings)
                      if i != best]

    def _again(self, t: Target, ref: Sample, ctx: PointContext, *, approach: bool) -> Sample:
        """Move away from ``t`` and back (or, ``approach``, to it from wherever the robot
        is), read the joints and measure: every move through the executor's checked
        moves (the motion guard, the joints read back), the reading through its dwell,
        quality-checked and fresh measurement and read-back (:meth:`PointContext.measure_at`)."""
        ctx = ctx.at(t)
        if approach and t.via is not None:
            ctx.move_entry()  # from elsewhere: a linear chain's start posture first
        if t.via is not None:
            prev = ctx.move_via()  # the plan's own approach
        elif approach:
            prev = ctx.read_joints().q
        else:
            prev = self.retract(t, ref)
            ctx.move_joints(prev)  # adaptive: near the planned posture
        # a linear move: the posture the point was read in (it fixes only the position)
        jr = (ctx.move_joints(ref.q) if t.move == "linear" and t.via is None
              else ctx.move_target())
        jr, m = ctx.measure_at(jr)
        cmd_q = np.asarray(t.q, float) if t.move == "joints" else jr.q
        env = m.env or {}
        return replace(ref, q=jr.q, tracker_p_smr=m.xyz, std_mm=m.std, n_averaged=m.n,
                       t_s=m.timestamp, temp_c=env.get("temp_c"),
                       pressure_hpa=env.get("pressure_hpa"),
                       humidity_pct=env.get("humidity_pct"), joints_t=jr.timestamp,
                       dirs=approach_dirs(prev, cmd_q, self.deadband_rad),
                       reflector=m.reflector or None, face=m.face or None, cov_mm2=m.cov)

    def retract(self, t: Target, ref: Sample) -> np.ndarray:
        """Joints a small step back from ``t`` against its approach (every joint when it
        was approached without motion), within the joint limits."""
        q = np.asarray(t.q if t.move == "joints" else ref.q, float)
        dirs = np.zeros(len(q)) if ref.dirs is None else np.asarray(ref.dirs, float)
        if not dirs.any():
            dirs = np.ones(len(q))
        away = np.clip(q - self.retract_rad * dirs, self.limits[:, 0], self.limits[:, 1])
        if self.model is None:
            return away
        p = tool_points(self.model, np.vstack([q, away]))
        dist = float(np.linalg.norm(p[1] - p[0]))
        if dist <= RETRACT_TOOL_MM:
            return away
        return q + (away - q) * (RETRACT_TOOL_MM / dist)  # the same direction, shorter


def _with_model(s: Sample, j: Judgement, verdict: str | None, remeasures: int | None = None
                ) -> Sample:
    return replace(s, verdict=verdict, model_residual_mm=j.residual_mm,
                   model_threshold_mm=j.threshold_mm,
                   remeasures=s.remeasures if remeasures is None else remeasures)
