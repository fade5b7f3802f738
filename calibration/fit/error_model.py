"""An :class:`ErrorModel`: a robot model plus a list of effects, as one function of a
parameter vector.

``bind(data)`` precomputes what the effects need from a data set;
``perturb(x, bound)`` applies the effects stage by stage to the chain's inputs (joints,
table, length scale, tool, base pose): the one place where an identified model is
applied, used by evaluation, compensation, model export and the zero-point command;
``evaluate(x, bound)`` returns the predicted target centres in the tracker frame
and the exact Jacobian with respect to every parameter, vectorised over poses;
``evaluate_pose(x, bound)`` adds a 6-DoF target's predicted orientations and their
Jacobian (:mod:`calibration.model.orientation_model`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, cast, overload

import numpy as np

from ..data.dataset import Dataset
from ..effects import DEFAULT_EFFECTS, Effect, parse_effects
from ..model.kinematics import A, ChainResult, D, run_chain
from ..model.orientation_model import target_orientations
from ..model.robot_model import RobotModel
from ..model.transforms import fit_rigid, matrix_to_rotvec, rotvec_to_matrix
from ..numerics.heap import keep_freed_memory

_STAGES = ("joint", "table", "length", "tool", "target", "base", "drift", "measure")
#: stages that need per-pose data (a bound data set) to be applied
_PER_POSE = ("joint", "length")
#: stages that are not the robot's chain: evaluated, never applied by :meth:`perturb`
_OUTSIDE_CHAIN = ("drift", "measure")


@dataclass
class Bound:
    """An error model's view of one data set: the data, the nominal chain, effect states."""

    data: Dataset
    #: the nominal chain on the data (a :class:`NominalChain`, which stands in for it)
    nominal: ChainResult
    states: list[Any]


class NominalChain:
    """The nominal model's :class:`~calibration.model.kinematics.ChainResult` for a data set, run
    at its first use (any attribute): the states of most effects never look at it, nor do
    the predictions on validation rows (0.2 ms per 1 000 poses of an identification)."""

    __slots__ = ("_run", "_result")

    def __init__(self, run: Callable[[], ChainResult]) -> None:
        self._run = run
        self._result: ChainResult | None = None

    @property
    def result(self) -> ChainResult:
        if self._result is None:
            self._result = self._run()
        return self._result

    def __getattr__(self, name: str) -> Any:
        return getattr(self.result, name)


@dataclass
class Perturbed:
    """The chain's inputs with the effects applied at a parameter vector, stage by stage.

    Attributes
    ----------
    q : (n, N) joints as they really are (reported + every joint-stage correction), rad;
        None when no data were bound
    table : (N, 5) nominal table plus the table-stage deltas (rad, mm)
    tool : (3,) target centre in the flange frame (tool stage, else the nominal tool), mm;
        (n, 3) per pose for a tool of several SMR nests with bound data
    length_scale : (n,) per-pose relative growth of the lengths (length stage), or None
    tracker_T_base : the base stage's pose of the robot base in the tracker frame, as
        (R (3, 3), t (3,)), or None
    flange_R_target : (3, 3) a 6-DoF target's orientation in the flange frame (target
        stage), or None (the flange's own orientation)
    applied : the stages an effect acted at
    skipped : indices of the effects not applied: per-pose stages (joint, length) without
        bound data, the drift stage (the cell over time) and the measure stage (the
        instrument): neither is the chain
    partials : effect index -> its stage hook's partial derivatives (for Jacobians)
    """

    q: np.ndarray | None
    table: np.ndarray
    tool: np.ndarray
    length_scale: np.ndarray | None = None
    tracker_T_base: tuple[np.ndarray, np.ndarray] | None = None
    flange_R_target: np.ndarray | None = None
    applied: set[str] = field(default_factory=set)
    skipped: list[int] = field(default_factory=list)
    partials: dict[int, np.ndarray] = field(default_factory=dict)


def _base_and_tool(Rf: np.ndarray, pf: np.ndarray, meas: np.ndarray,
                   t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The base (R, c) and the tool point t estimated together from the nominal flange
    poses (Rf (n, 3, 3), pf (n, 3)) and the measured points (n, 3), starting at t:
    alternating a rigid fit for the base and linear least squares for the tool."""
    for _ in range(8):
        R, c = fit_rigid(pf + Rf @ t, meas)
        # meas = R (pf + Rf t) + c  ->  (R Rf) t = meas - c - R pf, linear in t;
        # its columns are orthonormal per pose (sum of (R Rf)ᵀ(R Rf) = n I), so
        # the least-squares t is the mean of Rfᵀ (Rᵀ (meas - c) - pf)
        v = (meas - c) @ R - pf
        t_new = np.einsum("nji,nj->i", Rf, v) / len(v)
        done = np.linalg.norm(t_new - t) < 1e-9
        t = t_new
        if done:
            break
    R, c = fit_rigid(pf + Rf @ t, meas)
    return R, c, t


class ErrorModel:
    """A robot model with effects; parameters are the effects' parameters, concatenated.

    Parameters
    ----------
    model : the nominal robot
    effects : effect objects, or their names (``"geometric,base,tool,compliance:2"``)
    """

    def __init__(self, model: RobotModel,
                 effects: list[Effect] | list[str] | str = DEFAULT_EFFECTS) -> None:
        self.model = model
        by_name = isinstance(effects, str) or (
            isinstance(effects, list) and bool(effects) and isinstance(effects[0], str))
        self.effects: list[Effect] = (
            parse_effects(cast("str | list[str]", effects), model) if by_name
            else list(cast("list[Effect]", effects))
        )
        self.slices: list[slice] = []
        k = 0
        for e in self.effects:
            self.slices.append(slice(k, k + e.n_params))
            k += e.n_params
        self.n_params = k
        self.names = [n for e in self.effects for n in e.full_names]
        self.units = [u for e in self.effects for u in e.units]
        self.scales = (np.concatenate([e.scales for e in self.effects]) if self.effects
                       else np.zeros(0))
        self._table0 = model.dh_table()
        self._prismatic = model.prismatic_mask()
        self._by_stage = {
            s: [i for i, e in enumerate(self.effects) if e.stage == s] for s in _STAGES
        }

    # ---- naming -------------------------------------------------------------
    @property
    def labels(self) -> list[str]:
        """Effect names as on the command line."""
        return [e.label for e in self.effects]

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no parameter {name!r} in this error model") from None

    def effect_of(self, k: int) -> Effect:
        """The effect that owns parameter index k."""
        for e, sl in zip(self.effects, self.slices, strict=True):
            if sl.start <= k < sl.stop:
                return e
        raise IndexError(k)

    def with_effects(self, extra: list[Effect] | str) -> ErrorModel:
        """A new error model with more effects appended."""
        more = parse_effects(extra, self.model) if isinstance(extra, str) else list(extra)
        return ErrorModel(self.model, self.effects + more)

    # ---- evaluation -----------------------------------------------------------
    def bind(self, data: Dataset) -> Bound:
        # the first arrays over the poses are made here: from now on the heap keeps what
        # is freed (else the first identification's temporaries fault their pages in)
        keep_freed_memory()
        if data.n_joints != self.model.n_joints:
            raise ValueError(
                f"{data.source}: data have {data.n_joints} joints, model {self.model.name} "
                f"has {self.model.n_joints}"
            )
        nominal = NominalChain(lambda: run_chain(
            self.model.convention, self._table0, data.q, self.model.tool_mm(), jacobian=False,
            prismatic=self._prismatic,
        ))
        states = [e.bind(data, nominal) for e in self.effects]
        return Bound(data, cast(ChainResult, nominal), states)

    def initial(self, bound: Bound) -> np.ndarray:
        """Starting parameter vector: each effect's own start; with both a base and a tool
        effect, the two are estimated together from the nominal chain (alternating a rigid
        fit for the base and linear least squares for the tool), so an SMR far from the
        model's nominal tool needs no guess either."""
        x = np.zeros(self.n_params)
        for e, sl, st in zip(self.effects, self.slices, bound.states, strict=True):
            x[sl] = e.initial(bound.data, bound.nominal, st)
        base = [i for i in self._by_stage["base"] if self.effects[i].family == "base"]
        tool = [i for i in self._by_stage["tool"] if self.effects[i].family == "tool"]
        nom, data = bound.nominal, bound.data
        if base and tool and data.n >= 4:
            sb, st_ = self.slices[base[0]], self.slices[tool[0]]
            Rf, pf, meas = nom.base_R_flange, nom.base_p_flange, data.tracker_p_smr
            nests = getattr(self.effects[tool[0]], "nests", None)
            if nests is None:
                R, c, x[st_] = _base_and_tool(Rf, pf, meas, x[st_].copy())
            else:  # the base from the first nest's rows, then each nest's point under it
                nest = bound.states[tool[0]]
                t = x[st_].reshape(-1, 3).copy()
                first = nest == 0
                R, c, t[0] = _base_and_tool(Rf[first], pf[first], meas[first], t[0].copy())
                for k in range(1, len(nests)):
                    rows = nest == k
                    if rows.any():
                        v = (meas[rows] - c) @ R - pf[rows]
                        t[k] = np.einsum("nji,nj->i", Rf[rows], v) / int(rows.sum())
                x[st_] = t.ravel()
            x[sb] = np.concatenate([c, matrix_to_rotvec(R)])
        for i in self._by_stage["target"]:
            R_base = rotvec_to_matrix(x[self.slices[base[0]]][3:]) if base else np.eye(3)
            target: Any = self.effects[i]  # a target-stage effect: it has ``start_from``
            x[self.slices[i]] = target.start_from(data, R_base @ nom.base_R_flange)
        return x

    def normalize(self, x: np.ndarray) -> np.ndarray:
        """Canonical form of a parameter vector (e.g. base rotation vector within pi)."""
        x = np.array(x, float)
        effects: list[Any] = self.effects  # some have ``normalize``
        for e, sl in zip(effects, self.slices, strict=True):
            if hasattr(e, "normalize"):
                x[sl] = e.normalize(x[sl])
        return x

    def perturb(self, x: np.ndarray, bound: Bound | None = None) -> Perturbed:
        """Apply the effects at ``x`` to the chain's inputs, stage by stage (see
        :class:`Perturbed`). Without ``bound`` data, joint and length effects are skipped
        (they act per pose); the drift and measure stages are never applied here."""
        x = np.asarray(x, float)
        # each stage's effects have that stage's hook (see calibration.effects.base)
        eff: list[Any] = self.effects
        sls = self.slices
        out = Perturbed(None, self._table0, self.model.tool_mm())
        if bound is not None:
            data, sts = bound.data, bound.states
            out.q = data.q
            if self._by_stage["joint"]:
                out.q = data.q.copy()
                for i in self._by_stage["joint"]:
                    d, out.partials[i] = eff[i].delta(x[sls[i]], data, sts[i])
                    out.q[:, eff[i].joint - 1] += d
            for i in self._by_stage["length"]:
                out.length_scale, out.partials[i] = eff[i].length_scale(x[sls[i]], data,
                                                                       sts[i])
        for i in self._by_stage["table"]:
            d, out.partials[i] = eff[i].table_delta(x[sls[i]])
            out.table = out.table + d
        for i in self._by_stage["tool"]:
            if bound is not None and hasattr(eff[i], "tool_points"):  # SMR nests, per pose
                out.tool, out.partials[i] = eff[i].tool_points(x[sls[i]], bound.data,
                                                               bound.states[i])
            else:
                out.tool, out.partials[i] = eff[i].tool_point(x[sls[i]])
        for i in self._by_stage["target"]:
            out.flange_R_target, out.partials[i] = eff[i].target_rotation(x[sls[i]])
        for i in self._by_stage["base"]:
            if hasattr(eff[i], "transform"):
                out.tracker_T_base = eff[i].transform(x[sls[i]])
        for i, e in enumerate(eff):
            if e.stage in _OUTSIDE_CHAIN or (bound is None and e.stage in _PER_POSE):
                out.skipped.append(i)
            else:
                out.applied.add(e.stage)
        return out

    @overload
    def evaluate(self, x: np.ndarray, bound: Bound, jacobian: Literal[True] = ...,
                 joints: Literal[False] = ...) -> tuple[np.ndarray, np.ndarray]: ...

    @overload
    def evaluate(self, x: np.ndarray, bound: Bound, jacobian: Literal[False],
                 joints: Literal[False] = ...) -> tuple[np.ndarray, None]: ...

    @overload
    def evaluate(self, x: np.ndarray, bound: Bound, jacobian: Literal[True],
                 joints: Literal[True]) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    @overload
    def evaluate(self, x: np.ndarray, bound: Bound, jacobian: bool = ...,
                 joints: bool = ...) -> tuple[Any, ...]: ...

    def evaluate(
        self, x: np.ndarray, bound: Bound, jacobian: bool = True, joints: bool = False
    ) -> tuple[np.ndarray | None, ...]:
        """Predicted target centres in the tracker frame, and their Jacobian.

        Returns
        -------
        P : (n, 3) mm
        J : (n, 3, n_params), d P / d x (internal units), or None
        G : (n, 3, N), d P / d q_j in the tracker frame (only with ``joints=True``): the
            column any joint correction acts through
        """
        P, J, G, _, _ = self._evaluate(x, bound, jacobian, joints)
        if joints:
            return P, J, G
        return P, J

    @overload
    def evaluate_pose(self, x: np.ndarray, bound: Bound, jacobian: Literal[True] = ...
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]: ...

    @overload
    def evaluate_pose(self, x: np.ndarray, bound: Bound, jacobian: Literal[False]
                      ) -> tuple[np.ndarray, None, np.ndarray, None]: ...

    def evaluate_pose(self, x: np.ndarray, bound: Bound, jacobian: bool = True
                      ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray | None]:
        """:meth:`evaluate`, and the predicted orientations of a 6-DoF target.

        Returns
        -------
        P, J : as :meth:`evaluate`
        R : (n, 3, 3) ``tracker_R_target``
        W : (n, 3, n_params) its Jacobian as an angular velocity in the tracker frame,
            ``R(x + dx) = exp([W dx]x) R(x)`` (rad per internal unit), or None
        """
        P, J, _, c, r = self._evaluate(x, bound, jacobian, False)
        R, W = target_orientations(self, np.asarray(x, float), c, r, jacobian)
        return P, J, R, W

    def _evaluate(self, x: np.ndarray, bound: Bound, jacobian: bool, joints: bool) -> tuple[
            np.ndarray, np.ndarray | None, np.ndarray | None, Perturbed, ChainResult]:
        """:meth:`evaluate`: (P, J, G, the perturbed inputs, the chain's result)."""
        x = np.asarray(x, float)
        n = bound.data.n
        eff: list[Any] = self.effects  # each stage's effects have its hook
        sls = self.slices
        # J (None without the Jacobian), G (None without ``joints``) and the chain's
        # derivatives are used only under ``if jacobian`` / ``if joints`` below
        J: Any = np.zeros((n, 3, self.n_params)) if jacobian else None
        c = self.perturb(x, bound)
        table, tool, scale = c.table, c.tool, c.length_scale
        jacobian = jacobian or joints
        r = run_chain(self.model.convention, table, bound.data.q if c.q is None else c.q, tool,
                      scale, jacobian=jacobian, prismatic=self._prismatic)
        P = r.base_p_tcp
        G: Any = r.dP_dq if joints else None
        if jacobian:
            dP: Any = r.dP_dtable
            dP_internal: Any = r.dP_internal
            for i in self._by_stage["joint"]:
                j = eff[i].joint - 1
                J[:, :, sls[i]] = r.dP_dq[:, :, j][:, :, None] * c.partials[i][:, None, :]
            for i in self._by_stage["table"]:
                # (k, N*5) @ (N*5, 3n) on the chain's own storage layout
                part = c.partials[i]
                N = part.shape[0]
                block = part.reshape(N * 5, -1).T @ dP_internal.reshape(N * 5, 3 * n)
                J[:, :, sls[i]] = block.reshape(-1, 3, n).transpose(2, 1, 0)
            grow = None if scale is None else (1.0 + scale)[:, None, None]
            for i in self._by_stage["tool"]:
                # (n, 3, 3) x (3, k) as one product, not n small ones
                cols = (np.tensordot(r.base_R_flange, c.partials[i], axes=(2, 0))
                        if c.partials[i].ndim == 2
                        else np.matmul(r.base_R_flange, c.partials[i]))  # per-pose nests
                J[:, :, sls[i]] = cols if grow is None else cols * grow
            for i in self._by_stage["length"]:
                assert scale is not None  # a length-stage effect gave it
                lengths = dP[:, :, :, D] * table[:, D] + dP[:, :, :, A] * table[:, A]
                dP_ds = lengths.sum(axis=2) / (1.0 + scale)[:, None] + r.base_R_flange @ tool
                J[:, :, sls[i]] = dP_ds[:, :, None] * c.partials[i][:, None, :]
        for i in self._by_stage["base"]:
            P, R, Jb = eff[i].apply(x[sls[i]], P)
            if jacobian:
                J = np.matmul(R, J)
                J[:, :, sls[i]] = Jb
                if joints:
                    G = np.matmul(R, G)
        for i in self._by_stage["drift"]:
            d, part = eff[i].drift(x[sls[i]], bound.data, bound.states[i])
            P = P + d
            if jacobian:
                J[:, :, sls[i]] = part
        for i in self._by_stage["measure"]:
            P, factor, Jm = eff[i].measure(x[sls[i]], P)
            if jacobian:
                J = J * factor
                J[:, :, sls[i]] = Jm
                if joints:
                    G = G * factor
        return P, J, G, c, r

    def penalty(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Regularisation pseudo-observations of the effects that have them (mm), with their
        Jacobian (m, n_params); None when no effect is regularised."""
        rows, jacs = [], []
        effects: list[Any] = self.effects  # the regularised ones have ``penalty``
        for e, sl in zip(effects, self.slices, strict=True):
            if hasattr(e, "penalty"):
                r, Je = e.penalty(np.asarray(x, float)[sl])
                J = np.zeros((r.size, self.n_params))
                J[:, sl] = Je
                rows.append(r)
                jacs.append(J)
        if not rows:
            return None
        return np.concatenate(rows), np.vstack(jacs)

    def prepare(self, data: Dataset) -> Dataset:
        """Let every effect complete the data (in capture order) before any split."""
        for e in self.effects:
            data = e.prepare(data)
        return data

    def residuals(self, x: np.ndarray, bound: Bound) -> np.ndarray:
        """Measured minus predicted target centres, (n, 3) mm."""
        return bound.data.tracker_p_smr - self.evaluate(x, bound, jacobian=False)[0]

    def numeric_jacobian(self, x: np.ndarray, bound: Bound, rel: float = 1e-3) -> np.ndarray:
        """Central finite differences of :meth:`evaluate` (for tests), (n, 3, n_params)."""
        x = np.asarray(x, float)
        J = np.empty((bound.data.n, 3, self.n_params))
        for k in range(self.n_params):
            h = rel * max(float(self.scales[k]), abs(x[k]))
            xp, xm = x.copy(), x.copy()
            xp[k] += h
            xm[k] -= h
            J[:, :, k] = (
                self.evaluate(xp, bound, False)[0] - self.evaluate(xm, bound, False)[0]
            ) / (2 * h)
        return J
