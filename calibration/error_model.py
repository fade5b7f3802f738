"""An :class:`ErrorModel`: a robot model plus a list of effects, as one function of a
parameter vector.

``bind(data)`` precomputes what the effects need from a data set;
``evaluate(x, bound)`` returns the predicted target centres in the tracker frame
and the exact Jacobian with respect to every parameter, vectorised over poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .dataset import Dataset
from .effects import DEFAULT_EFFECTS, Effect, parse_effects
from .kinematics import A, ChainResult, D, run_chain
from .robot_model import RobotModel
from .transforms import fit_rigid, matrix_to_rotvec

_STAGES = ("joint", "table", "length", "tool", "base", "measure")


@dataclass
class Bound:
    """An error model's view of one data set: the data, the nominal chain, effect states."""

    data: Dataset
    nominal: ChainResult
    states: list[Any]


class ErrorModel:
    """A robot model with effects; parameters are the effects' parameters, concatenated.

    Parameters
    ----------
    model : the nominal robot
    effects : effect objects, or their names (``"geometric,base,tool,compliance:2"``)
    """

    def __init__(self, model: RobotModel, effects: list[Effect] | str = DEFAULT_EFFECTS):
        self.model = model
        self.effects: list[Effect] = (
            parse_effects(effects, model) if isinstance(effects, (str, list)) and (
                isinstance(effects, str) or (effects and isinstance(effects[0], str))
            ) else list(effects)
        )
        self.slices: list[slice] = []
        k = 0
        for e in self.effects:
            self.slices.append(slice(k, k + e.n_params))
            k += e.n_params
        self.n_params = k
        self.names = [n for e in self.effects for n in e.full_names]
        self.units = [u for e in self.effects for u in e.units]
        self.scales = np.concatenate([e.scales for e in self.effects]) if self.effects else []
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
        if data.n_joints != self.model.n_joints:
            raise ValueError(
                f"{data.source}: data have {data.n_joints} joints, model {self.model.name} "
                f"has {self.model.n_joints}"
            )
        nominal = run_chain(
            self.model.convention, self._table0, data.q, self.model.tool_mm(), jacobian=False,
            prismatic=self._prismatic,
        )
        states = [e.bind(data, nominal) for e in self.effects]
        return Bound(data, nominal, states)

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
        if base and tool and bound.data.n >= 4:
            sb, st_ = self.slices[base[0]], self.slices[tool[0]]
            nom = bound.nominal
            Rf, pf, meas = nom.flange_R, nom.flange_p, bound.data.xyz
            t = x[st_].copy()
            for _ in range(8):
                R, c = fit_rigid(pf + Rf @ t, meas)
                # meas = R (pf + Rf t) + c  ->  (R Rf) t = meas - c - R pf, linear in t
                A = (R @ Rf).reshape(-1, 3)
                b = (meas - c - pf @ R.T).ravel()
                t_new = np.linalg.lstsq(A, b, rcond=None)[0]
                done = np.linalg.norm(t_new - t) < 1e-9
                t = t_new
                if done:
                    break
            R, c = fit_rigid(pf + Rf @ t, meas)
            x[sb] = np.concatenate([c, matrix_to_rotvec(R)])
            x[st_] = t
        return x

    def normalize(self, x: np.ndarray) -> np.ndarray:
        """Canonical form of a parameter vector (e.g. base rotation vector within pi)."""
        x = np.array(x, float)
        for e, sl in zip(self.effects, self.slices, strict=True):
            if hasattr(e, "normalize"):
                x[sl] = e.normalize(x[sl])
        return x

    def evaluate(
        self, x: np.ndarray, bound: Bound, jacobian: bool = True, joints: bool = False
    ):
        """Predicted target centres in the tracker frame, and their Jacobian.

        Returns
        -------
        P : (n, 3) mm
        J : (n, 3, n_params), d P / d x (internal units), or None
        G : (n, 3, N), d P / d q_j in the tracker frame (only with ``joints=True``): the
            column any joint correction acts through
        """
        x = np.asarray(x, float)
        data = bound.data
        n = data.n
        eff, sls, sts = self.effects, self.slices, bound.states
        J = np.zeros((n, 3, self.n_params)) if jacobian else None

        q = data.q
        joint_parts = []
        if self._by_stage["joint"]:
            q = q.copy()
            for i in self._by_stage["joint"]:
                d, part = eff[i].delta(x[sls[i]], data, sts[i])
                q[:, eff[i].joint - 1] += d
                joint_parts.append((i, eff[i].joint - 1, part))
        table = self._table0
        table_parts = []
        for i in self._by_stage["table"]:
            d, part = eff[i].table_delta(x[sls[i]])
            table = table + d
            table_parts.append((i, part))
        scale = None
        length_part = None
        for i in self._by_stage["length"]:
            scale, part = eff[i].length_scale(x[sls[i]], data, sts[i])
            length_part = (i, part)
        tool = self.model.tool_mm()
        tool_part = None
        for i in self._by_stage["tool"]:
            tool, part = eff[i].tool_point(x[sls[i]])
            tool_part = (i, part)

        jacobian = jacobian or joints
        r = run_chain(self.model.convention, table, q, tool, scale, jacobian=jacobian,
                      prismatic=self._prismatic)
        P = r.point
        G = r.dP_dq if joints else None
        if jacobian:
            dP = r.dP_dtable
            dq = r.dP_dq
            for i, j, part in joint_parts:
                J[:, :, sls[i]] = dq[:, :, j][:, :, None] * part[:, None, :]
            for i, part in table_parts:
                # (k, N*5) @ (N*5, 3n) on the chain's own storage layout
                N = part.shape[0]
                block = part.reshape(N * 5, -1).T @ r.dP_internal.reshape(N * 5, 3 * n)
                J[:, :, sls[i]] = block.reshape(-1, 3, n).transpose(2, 1, 0)
            grow = None if scale is None else (1.0 + scale)[:, None, None]
            if tool_part is not None:
                i, part = tool_part
                cols = r.flange_R @ part
                J[:, :, sls[i]] = cols if grow is None else cols * grow
            if length_part is not None:
                i, part = length_part
                lengths = dP[:, :, :, D] * table[:, D] + dP[:, :, :, A] * table[:, A]
                dP_ds = lengths.sum(axis=2) / (1.0 + scale)[:, None] + r.flange_R @ tool
                J[:, :, sls[i]] = dP_ds[:, :, None] * part[:, None, :]
        for i in self._by_stage["base"]:
            P, R, Jb = eff[i].apply(x[sls[i]], P)
            if jacobian:
                J = np.matmul(R, J)
                J[:, :, sls[i]] = Jb
                if joints:
                    G = np.matmul(R, G)
        for i in self._by_stage["measure"]:
            P, factor, Jm = eff[i].measure(x[sls[i]], P)
            if jacobian:
                J = J * factor
                J[:, :, sls[i]] = Jm
                if joints:
                    G = G * factor
        if joints:
            return P, J, G
        return P, J

    def penalty(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Regularisation pseudo-observations of the effects that have them (mm), with their
        Jacobian (m, n_params); None when no effect is regularised."""
        rows, jacs = [], []
        for e, sl in zip(self.effects, self.slices, strict=True):
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
        return bound.data.xyz - self.evaluate(x, bound, jacobian=False)[0]

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
