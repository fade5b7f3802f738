"""cellcal's calibration core: models, kinematics, effects, identification.

Numbers only: imports nothing from the other cellcal packages, draws nothing, prints
nothing (figures, the HTML report and the command line's JSON live in ``presentation``).
Lengths mm, angles rad inside.

Rooms, each importing only the rooms below it (the ``layers`` contract of pyproject.toml):

Modules
-------
workflow      staged_fit: uncalibrated -> current -> current + the recommended effect
compensation/ compensated joints and corrected targets, a program's targets, controller joints
zero_point/   zero-point recalibration from 20 postures on one fixed point
diagnosis/    where a fit fails and which missing effect explains it; the auto loop; history
exports/      params.json, model YAML, controller files and URDF, with parity checks
fit/          the error model, identification, solvers, outliers, uncertainty, simulation
cell/         the cell YAML, the tracker's line of sight, the frame routine's fits
effects/      the physical causes of error (geometric, base, tool, compliance, ...)
data/         the Dataset and the measurement CSV, the column table, the capture's context
model/        the nominal robot: models, kinematics, inverse kinematics, transforms, gravity
numerics/     linear algebra, the chi(3) quantile, BLAS threads, the heap, memory
errors        the core's error family, each with its exit code
files         reading inputs strictly and writing outputs atomically (one helper each)
version       the software's version, as recorded with runs and calibrations
"""

from .data.dataset import DataError, Dataset, load_csv
from .effects import DEFAULT_EFFECTS, Effect, EffectError, JointEffect, parse_effects
from .fit.error_model import ErrorModel
from .fit.identify import Fit, error_stats, identify
from .model.kinematics import forward, run_chain, tool_points
from .model.model_loading import load_model
from .model.robot_model import ModelError, RobotModel, builtin_models

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
