"""``zero20``: the 20-posture, 4-plane zero-point routine.

20 different postures, 5 on each of 4 vertical planes through a fixed target
point, each bringing the tool tip to the target
(:func:`calibration.zero_point.zero20_postures` on the nominal model). Each
point is a ``zero`` target: the executor moves to the posture, then the routine's
acquisition (:class:`ZeroLoop`, the executor's adaptive-acquisition hook) closes
the loop with the tracker — damped-least-squares joint corrections until the
measured tip is on the target within ``tol_mm`` (the target in the tracker frame
is fixed by the first posture) — and the executor records the joints. The loop's
settings are :class:`ZeroLoopOptions` (on the command line ``--zero-tol-mm``,
``--zero-average``), stored in the run context's ``acquire`` options.

The loop is bounded: each correction moves the tip by at most ``max_step_mm``; every
move it makes (corrections, probes) passes the executor's motion guard, which keeps it
within the run's deviation limits of the planned posture, the joint limits and above
the floor; a posture whose tip starts more than ``max_error_mm`` from the target is not
corrected at all; and every measured tip displacement must agree with the one its
correction predicts (``agree_rel`` of it, plus ``agree_abs_mm`` and the measurements'
noise) — a jump of the tracker reading or a measurement frame of another cell stops the
loop with :class:`~daq.errors.ZeroDiverged` naming the point (the run pauses).

Needs an arm that can orient its tool (6 joints or more): a smaller arm reaches
a point in too few postures.

Line of sight (``cell`` with a tracker position): the 20 SMR axes gather about the
direction from the target to the tracker, tilted within the acceptance cone less the
margin (instead of the tool pointing down at the target), so the tracker sees every
posture; postures whose beam a link would block are avoided by trying the postures in
one shoulder configuration, and a plan the tracker would not see is refused
(:class:`~daq.errors.NotEnoughVisible`). The postures are visited in a short order
(:func:`daq.plans.shortest_order`).

Replay (``--replay RUN``, :func:`replay_plan`): the same 20 postures again, from
the joints recorded in run RUN's samples (not re-solved): for the seed method's
second, fine pass after a manual adjustment of the joint zeros. The executor
moves to each recorded posture and closes the loop again from there.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from calibration.model.transforms import fit_rigid

from ..errors import NotEnoughVisible, ZeroDiverged, ZeroNotReached
from ..plans import Plan, Target, shortest_order
from ..store import RunSummary
from ._common import hidden, knows_tracker, visibility_params


def make_plan(model, *, target_xyz=None, seed_deg=None, seed: int = 0,
              replay: dict | None = None, cell=None) -> Plan:
    """The zero20 plan.

    Parameters
    ----------
    model : RobotModel
    target_xyz : sequence of 3 float
        The fixed target point (mm, base frame).
    seed_deg : sequence of float, optional
        Preferred configuration (deg).
    seed : int
        Seed of the IK's extra random starts.
    replay : dict, optional
        Replay recorded postures instead (see :func:`replay_plan`): keys ``run``
        (source run id), ``q`` ((20, N) joints read, rad), ``plane`` ((20,)), ``label``
        (20 str), ``target_xyz_mm`` (the source plan's target, mm).
    cell : CellSpec, optional
        Plan for the tracker's line of sight (see the module docstring).
    """
    if replay is not None:
        return replay_plan(model, **replay)

    if model.n_joints < 6:
        raise ValueError(f"zero20: model {model.name} has {model.n_joints} joints; 20 distinct "
                         "postures on one point need an arm that orients its tool (6+ joints)")
    if model.prismatic_mask() is not None:
        raise ValueError(f"zero20: model {model.name} has a prismatic joint: the zero-point "
                         "routine handles revolute joints only")
    if target_xyz is None:
        raise ValueError("zero20: the target point is required (--target-xyz X,Y,Z)")
    target = np.asarray(target_xyz, float)
    q_seed = np.radians(seed_deg) if seed_deg is not None else None
    q, plane = _postures(model, target, q_seed, seed, cell)
    order = shortest_order(q, 1.0)
    per = {}
    labels = []
    for i in range(len(q)):
        k = int(plane[i])
        per[k] = per.get(k, 0) + 1
        labels.append(f"p{k}.{per[k]}")
    targets = [Target(n, "zero", q=q[i], base_p_tcp=target, label=labels[i],
                      info={"plane": int(plane[i])}) for n, i in enumerate(order)]
    params = {"target_xyz_mm": target.tolist(),
              "seed_deg": None if q_seed is None else np.degrees(q_seed).tolist(), "seed": seed}
    if knows_tracker(cell):
        params["visibility"] = visibility_params(cell)
    return Plan("zero20", params, tuple(targets), model=model.name)


def _postures(model, target: np.ndarray, q_seed, seed: int, cell):
    """The 20 postures (rad) and their planes: facing the tracker when ``cell`` knows it."""
    from calibration.zero_point import zero20_postures

    sight = knows_tracker(cell)
    options = {}
    if sight:
        cone = max(cell.smr.half_angle_deg - cell.margins.facing_deg - 0.5, 0.0)  # 0.5: IK
        options = {"about": cell.tracker_mm - target, "axis_flange": cell.smr.axis_unit(),
                   "tilts_deg": (-cone, -cone / 2, 0.0, cone / 2, cone)}
    tried = []
    for flip in (True, False) if sight else (True,):
        q, plane, ok = zero20_postures(model.convention, model.dh_table(), model.tool_mm(),
                                       target, q_seed=q_seed, limits=model.limits_rad(),
                                       rng=np.random.default_rng(seed), flip_shoulder=flip,
                                       **options)
        if not ok.all():
            bad = (np.flatnonzero(~ok) + 1).tolist()
            tried.append(f"postures {bad} cannot reach the target")
            continue
        blocked = hidden(model, q, cell) if sight else []
        if not blocked:
            return q, plane
        tried.append("; ".join(f"posture {i + 1}: {why}" for i, why in blocked[:5]))
    if not sight:
        raise ValueError(f"zero20: {tried[0]} {target.tolist()} mm")
    raise NotEnoughVisible(
        f"zero20: no 20 postures on {target.tolist()} mm that the tracker at "
        f"{np.round(cell.tracker_mm).tolist()} mm ({cell.tracker_source}) sees: "
        f"{' / '.join(tried)}; change: another --target-xyz (between the robot and the "
        "tracker, well within reach), --seed-deg, or move the tracker")


def replay_plan(model, *, run: int, q, plane, label, target_xyz_mm) -> Plan:
    """A zero20 plan that replays the postures recorded in run ``run``.

    Parameters
    ----------
    model : RobotModel
    run : int
        The source run (recorded in the plan's parameters).
    q : (n, N) array
        Joints read at each recorded posture, rad (the new targets, not re-solved).
    plane : (n,) int
        Plane 1..4 of each posture.
    label : sequence of str
        The postures' labels (kept).
    target_xyz_mm : sequence of 3 float
        The source plan's nominal target point (mm, base frame).
    """
    q = np.atleast_2d(np.asarray(q, float))
    if q.shape[1] != model.n_joints:
        raise ValueError(f"zero20 --replay {run}: the run has {q.shape[1]} joints, model "
                         f"{model.name} has {model.n_joints}")
    target = np.asarray(target_xyz_mm, float)
    targets = tuple(Target(i, "zero", q=q[i], base_p_tcp=target, label=str(label[i]),
                           info={"plane": int(plane[i])}) for i in range(len(q)))
    params = {"target_xyz_mm": target.tolist(), "replay_run": int(run)}
    return Plan("zero20", params, targets, model=model.name)


def replay_source(store, run_id: int) -> dict:
    """The ``replay`` argument of :func:`make_plan` from run ``run_id`` of the open store.

    The run must be a completed ``zero20`` run; ValueError otherwise.
    """
    from ..store import StoreError

    try:
        r = store.run(run_id)
    except StoreError as e:
        raise ValueError(f"--replay {run_id}: {e}") from None
    if r.routine != "zero20" or r.status != "completed":
        raise ValueError(f"--replay {run_id}: run {run_id} is a {r.status} {r.routine} run, "
                         "not a completed zero20 run")
    s = store.samples(r.id)
    src = Plan.from_json(r.plan_json)
    return {"run": r.id, "q": s.q, "label": s.pose_id,
            "plane": [int(t["info"]["plane"]) for t in s.target],
            "target_xyz_mm": src.params["target_xyz_mm"]}


def resolve_params(params: dict, open_store) -> dict:
    """``replay_run`` (``--replay RUN``) resolved against the run store: the recorded
    postures (``open_store()`` opens it, only for a replay)."""
    run_id = params.get("replay_run")
    if run_id is None:
        return params
    try:
        with open_store() as store:
            return {"replay": replay_source(store, run_id)}
    except ValueError as e:
        if str(e).startswith("--replay"):
            raise
        raise ValueError(f"--replay {run_id}: {e}") from None


def finalize(plan: Plan, samples, run) -> dict:
    """Spread of the measured tips (they should all be on the target)."""
    xyz = samples.tracker_p_smr
    spread = np.linalg.norm(xyz - xyz.mean(axis=0), axis=1)
    summary = run.summary or RunSummary()
    summary.tip_spread_max_mm = float(spread.max())
    summary.tip_spread_rms_mm = float(np.sqrt(np.mean(spread**2)))
    return {"summary": summary}


# ------------------------------------------------------------ the closed loop
class ZeroLoopOptions(BaseModel):
    """Settings of the zero-point closed loop (mm, rad)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    #: the tip is on the target within this, mm
    tol_mm: float = 0.01
    #: corrections at the most per posture
    max_iter: int = 25
    #: damping of the least-squares corrections, mm
    damping_mm: float = 1.0
    #: size of the three probe moves that measure the tracker's orientation when the run
    #: has no measurement frame, mm
    probe_mm: float = 5.0
    #: the loop also stops once the tip is within this many times the 3-D std of the
    #: measurement (a tolerance below the tracker's noise cannot be confirmed)
    noise_k: float = 1.5
    #: tracker measurements averaged per step (their mean's std is taken as std/sqrt(n):
    #: independent measurements; a tracker whose noise is correlated over seconds gains less)
    average: int = 1
    #: the loop stops only after a correction that moved the tip by at most this (mm): a
    #: large correction leaves a residual along its own direction (model Jacobian, tracker
    #: rotation: ~1 %) that is systematic, not noise, and would bias the offsets
    confirm_step_mm: float = 0.5
    #: the largest tip motion of one correction, mm (a larger one is scaled down)
    max_step_mm: float = Field(5.0, gt=0)
    #: a tip measured further than this from the target at the planned posture is not
    #: corrected (mm): the robot's own errors are smaller; a moved tracker is not
    max_error_mm: float = Field(25.0, gt=0)
    #: a measured tip displacement may differ from the predicted one by this fraction of
    #: it, plus ``agree_abs_mm`` and 4 times the two measurements' combined 3-D std
    agree_rel: float = Field(0.3, gt=0)
    agree_abs_mm: float = Field(0.05, ge=0)
    #: every correction (and probe move, and the posture itself before the first
    #: measurement) first moves each joint this far below its new position, then to it
    #: (rad): each joint approaches from the same side, so backlash stays on one side
    #: instead of flipping with the sign of the correction (a loop that alternates sides
    #: never converges), and every recorded posture was approached from below (+1) on
    #: every joint; 0 moves straight there
    approach_rad: float = Field(default=0.002, ge=0.0, le=0.05)


#: the routine's acquisition options (stored in the run context's ``acquire``)
ACQUIRE_OPTIONS = ZeroLoopOptions

def acquisition(model, context) -> ZeroLoop:
    """The run's closed loop, from its context (options, measurement frame)."""
    T = context.tracker_T_base_matrix
    return ZeroLoop(model, ZeroLoopOptions(**context.acquire),
                    None if T is None else T[:3, :3])


def tool_jacobian(model, q: np.ndarray) -> np.ndarray:
    """d(tool point)/dq of the nominal model at ``q`` (rad, (N,)): shape (3, N), mm/rad."""
    from calibration.model.kinematics import run_chain

    r = run_chain(model.convention, model.dh_table(), np.asarray(q, float)[None],
                  model.tool_mm(), jacobian=True)
    return r.dP_dtable[0, :, :, 0]


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation R (3x3) minimising sum |R a_i - b_i|^2 (displacements, (n, 3)).

    :func:`calibration.model.transforms.fit_rigid` on the displacements and their mirror
    images: their centroids are the origin, so the best rigid fit is a rotation alone.
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    R, _ = fit_rigid(np.vstack([a, -a]), np.vstack([b, -b]))
    return R


class ZeroLoop:
    """Damped-least-squares joint corrections until the tool tip is on the target.

    An :class:`~daq.executor.Acquisition`: the executor has moved to the posture; the
    loop measures, corrects and measures again through the executor's
    :class:`~daq.executor.PointContext`, and returns the joints and the measurement
    of the tip on the target. The tool Jacobian comes from the nominal model (base
    frame), turned into the tracker frame with the rotation tracker <- base
    (:meth:`rotation`). The loop stops when the measured tip is within ``tol_mm`` of
    the target, or within ``noise_k`` times the measurement's own 3-D std when that is
    larger, and the last correction moved the tip by at most ``confirm_step_mm`` (else
    one more correction: after a large one, the tip's residual error is systematic).

    Parameters
    ----------
    model : RobotModel
        The nominal model (with the controller's tool).
    options : ZeroLoopOptions
    tracker_R_base : (3, 3) or None
        From the run's measurement frame; None: measured by probe moves.
    """

    def __init__(self, model, options: ZeroLoopOptions | None = None,
                 tracker_R_base: np.ndarray | None = None) -> None:
        self.model = model
        self.o = options or ZeroLoopOptions()
        self.tracker_R_base = tracker_R_base

    def move(self, ctx, q: np.ndarray):
        """Move to ``q`` (rad), every joint approaching from below (``approach_rad``);
        the joints read back there."""
        q = np.asarray(q, float)
        if self.o.approach_rad > 0:
            ctx.move_joints(q - self.o.approach_rad)
        return ctx.move_joints(q)

    def measure(self, ctx):
        """The mean of ``average`` measurements."""
        from dataclasses import replace

        k = max(1, int(self.o.average))
        ms = [ctx.measure() for _ in range(k)]
        if k == 1:
            return ms[0]
        std = np.sqrt(np.mean([m.std**2 for m in ms], axis=0) / k)
        return replace(ms[-1], xyz=np.mean([m.xyz for m in ms], axis=0), std=std,
                       n=int(sum(m.n for m in ms)))

    def target(self, ctx, m_xyz: np.ndarray) -> np.ndarray:
        """The zero-point target in the tracker frame: fixed by the run's first zero point
        (kept in the run summary, ``zero_target_tracker_mm``)."""
        summary = ctx.summary()
        if summary.zero_target_tracker_mm is None:
            summary.zero_target_tracker_mm = [float(v) for v in m_xyz]
            ctx.save_summary(summary)
        return np.asarray(summary.zero_target_tracker_mm, float)

    def _allowed(self, predicted: np.ndarray, m0, m1) -> float:
        """How far a measured displacement may be from the predicted one (mm)."""
        o = self.o
        noise = float(np.sqrt(np.sum(np.asarray(m0.std) ** 2) + np.sum(np.asarray(m1.std) ** 2)))
        return o.agree_rel * float(np.linalg.norm(predicted)) + o.agree_abs_mm + 4.0 * noise

    def _where(self, ctx) -> str:
        t = getattr(ctx, "target", None)
        return "zero" if t is None else f"zero point {t.index} ({t.label})"

    def rotation(self, ctx, jr, m):
        """Rotation tracker <- base (3x3) for the loop, and the current state.

        From the run's measurement frame when known; else from the run summary
        (``zero_tracker_R_base``, measured earlier in this run); else measured now: three
        probe moves of ``probe_mm`` along the base axes (nominal model), their nominal
        tip displacements matched to the measured ones (:func:`rotation_between`). The
        tracker may stand in any orientation: with a wrong rotation the corrections point
        the wrong way (the loop diverges beyond 90 degrees).

        Returns
        -------
        R : (3, 3) tracker_R_base
        jr, m : the joints read and the measurement at the robot's current position
        """
        if self.tracker_R_base is not None:
            return np.asarray(self.tracker_R_base, float), jr, m
        summary = ctx.summary()
        if summary.zero_tracker_R_base is not None:
            return np.asarray(summary.zero_tracker_R_base, float), jr, m
        from calibration.model.inverse import ChainFK

        fk = ChainFK.from_model(self.model)
        q0 = np.asarray(jr.q, float)
        if self.o.approach_rad > 0:  # the reference measured like the probes: from below
            jr = self.move(ctx, q0)
            m = self.measure(ctx)
            q0 = np.asarray(jr.q, float)
        p0 = fk.point(q0[None])[0]
        m0 = np.asarray(m.xyz, float)
        A, B, ms = [], [], []
        for k in range(3):
            dp = np.zeros(3)
            dp[k] = self.o.probe_mm
            dq = np.linalg.lstsq(tool_jacobian(self.model, q0), dp, rcond=None)[0]
            jr = self.move(ctx, q0 + dq)
            m = self.measure(ctx)
            A.append(fk.point(np.asarray(jr.q, float)[None])[0] - p0)
            B.append(np.asarray(m.xyz, float) - m0)
            ms.append(m)
        R = rotation_between(np.array(A), np.array(B))
        for a, b, mk in zip(A, B, ms, strict=True):
            miss = float(np.linalg.norm(R @ a - b))
            if miss > self._allowed(R @ a, m, mk):
                raise ZeroDiverged(f"robot {ctx.robot_url}", self._where(ctx), (
                    f"the probe moves disagree ({miss:.3f} mm from one rotation): the tracker "
                    "reading jumped while probing; nothing was stored"))
        summary.zero_tracker_R_base = R.tolist()
        ctx.save_summary(summary)
        return R, jr, m

    def acquire(self, t: Target, ctx):
        """Close the loop at the posture the robot stands in; (joints read, measurement).

        :class:`~daq.errors.ZeroDiverged` when the tip starts beyond ``max_error_mm`` or a
        measured displacement disagrees with its correction's prediction;
        :class:`~daq.errors.ZeroNotReached` after ``max_iter`` corrections.
        """
        from calibration.model.inverse import ChainFK

        o = self.o
        dev = f"robot {ctx.robot_url}"
        jr = ctx.read_joints()
        if o.approach_rad > 0:  # the posture itself approached from below, like every step
            jr = self.move(ctx, jr.q)
        m = self.measure(ctx)
        target = self.target(ctx, m.xyz)
        e0 = float(np.linalg.norm(target - m.xyz))
        if e0 > o.max_error_mm:
            raise ZeroDiverged(dev, self._where(ctx), (
                f"the tip measures {e0:.1f} mm from the zero-point target at the planned "
                f"posture (at most {o.max_error_mm:g} mm): has the tracker, its SMR nest or "
                "the measurement frame moved? Nothing was corrected"))
        R, jr, m = self.rotation(ctx, jr, m)
        fk = ChainFK.from_model(self.model)
        lam2 = o.damping_mm**2
        last_step = 0.0  # the tip motion of the last correction, mm
        for k in range(o.max_iter):
            e = target - m.xyz
            tol = max(o.tol_mm, o.noise_k * float(np.linalg.norm(m.std)))
            if float(np.linalg.norm(e)) <= tol and last_step <= o.confirm_step_mm:
                return jr, m
            J = R @ tool_jacobian(self.model, jr.q)
            dq = J.T @ np.linalg.solve(J @ J.T + lam2 * np.eye(3), e)
            step = float(np.linalg.norm(J @ dq))
            if step > o.max_step_mm:  # a bounded correction
                dq *= o.max_step_mm / step
            p_before, m_before = fk.point(np.asarray(jr.q, float)[None])[0], m
            jr = self.move(ctx, jr.q + dq)
            m = self.measure(ctx)
            predicted = R @ (fk.point(np.asarray(jr.q, float)[None])[0] - p_before)
            measured = np.asarray(m.xyz, float) - np.asarray(m_before.xyz, float)
            last_step = float(np.linalg.norm(predicted))
            miss = float(np.linalg.norm(measured - predicted))
            allowed = self._allowed(predicted, m_before, m)
            if miss > allowed:
                raise ZeroDiverged(dev, self._where(ctx), (
                    f"correction {k + 1}: the tip moved {np.round(measured, 3).tolist()} mm "
                    f"where the correction predicts {np.round(predicted, 3).tolist()} mm "
                    f"({miss:.3f} mm apart, at most {allowed:.3f}): the tracker reading jumped, "
                    "or the measurement frame is not this cell's; the loop stopped"))
        raise ZeroNotReached(dev, self._where(ctx),
                             f"tip {np.linalg.norm(target - m.xyz):.4f} mm from the target "
                             f"after {o.max_iter} corrections: the robot does not follow the "
                             "loop's corrections (backlash beyond --zero-approach-rad "
                             f"{o.approach_rad:g}? the tracker noisier than --zero-tol-mm "
                             f"{o.tol_mm:g}? then --zero-average N or a larger --zero-tol-mm)")
