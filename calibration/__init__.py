"""cellcal's calibration core: models, kinematics, effects, identification.

Numbers only; imports nothing from the other cellcal packages.
"""

from .dataset import DataError, Dataset, load_csv
from .effects import DEFAULT_EFFECTS, Effect, EffectError, JointEffect, parse_effects
from .error_model import ErrorModel
from .identify import Fit, error_stats, identify
from .kinematics import forward, run_chain, tool_points
from .robot_model import ModelError, RobotModel, builtin_models, load_model

__all__ = [
    "DEFAULT_EFFECTS",
    "DataError",
    "Dataset",
    "Effect",
    "EffectError",
    "ErrorModel",
    "Fit",
    "JointEffect",
    "ModelError",
    "RobotModel",
    "builtin_models",
    "error_stats",
    "forward",
    "identify",
    "load_csv",
    "load_model",
    "parse_effects",
    "run_chain",
    "tool_points",
]
