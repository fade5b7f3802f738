"""``models``: the built-in robot models, one :class:`ModelSummary` each
(:func:`builtin_model_summaries`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from calibration import builtin_models, load_model


@dataclass(frozen=True)
class ModelSummary:
    """A built-in model: its name, DH convention, joints, whether it has a mass model (for
    compliance), and the sum of |a| + |d| over its joints (a reach scale, mm, 0.1 mm)."""

    name: str
    convention: str
    joints: int
    mass_model: bool
    reach_mm: float

    def to_json(self) -> dict:
        """The ``models --json`` entry."""
        return asdict(self)


def builtin_model_summaries() -> list[ModelSummary]:
    """Every built-in model, in :func:`calibration.builtin_models` order."""
    out = []
    for name in builtin_models():
        m = load_model(name)
        reach = sum(abs(j.a) + abs(j.d) for j in m.joints)
        out.append(ModelSummary(name, m.convention, m.n_joints, m.links is not None,
                                round(reach, 1)))
    return out
