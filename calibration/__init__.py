"""cellcal's calibration core: models, kinematics, effects, identification.

Numbers only: imports nothing from the other cellcal packages, draws nothing, prints
nothing (figures, the HTML report and the command line's JSON live in ``presentation``).
Lengths mm, angles rad inside.

Modules
-------
robot_model     RobotModel: the nominal robot from the model YAML (docs/formats.md §2), built-ins
kinematics      run_chain: forward kinematics vectorised over poses, exact Jacobians
transforms      rotations and rigid transforms on arrays; fit_rigid / fit_rotation (Kabsch)
inverse         batched damped-Newton inverse kinematics (ChainFK, solve_ik)
gravity         gravity torques at every joint from the mass model
files           reading inputs strictly and writing outputs atomically (one helper each)
dataset         Dataset and the measurement CSV (docs/formats.md §1), CsvTable for every table
columns         the column table: every per-point quantity once (CSV, store, Dataset)
capture_meta    CaptureMeta: the capture context a measurement file carries (tool, frame, run)
data_quality    data too poor to identify a model: refused (InsufficientData), not fitted
effects/        the physical causes of error (geometric, base, tool, compliance, ...)
error_model     ErrorModel: a model plus effects; perturb (the one apply chain), evaluate
identifiability which parameters a data set determines (QR with column pivoting)
solvers/        lm, ridge, besa, sa: the least-squares solvers identify uses
blas            one BLAS thread for small problems (timings independent of the neighbours)
linalg          Cholesky solves and pivoted QR on numpy alone (no scipy on calibrate's path)
chi3            the chi distribution with 3 degrees of freedom: tail and quantile
identify        identify -> Fit (values, uncertainties, residuals, statistics), fit_at
uncertainty     correlations, Monte-Carlo re-identification, position uncertainty
diagnosis       diagnose: where a fit fails and which missing effect explains it
screening       candidates screened at a linearised fit (linear_screen: the formulas;
                candidate_columns; table_screening: spacing and smoothing by GCV; f_test)
workflow        staged_fit: uncalibrated -> current -> current + the recommended effect
params_io       params.json: a fit's parameters written and read back
compensation    compensated joints and corrected targets from a calibration
model_export    the calibrated model as model YAML and UR calibration.conf deltas
ur_conf         UR calibration.conf deltas and the exact conversion to pure DH
zero_point/     zero-point recalibration from 20 postures on one fixed point
frame_fit       circle, line and measurement-frame fits of the frame routine
cell            CellSpec: the cell YAML (tracker position, SMR axis and reflector, fixtures)
visibility      the tracker's line of sight: facing angle, link capsules, fixtures, facing IK
sight_cause     why no pose is visible: the SMR inside the wrist, the constraint hiding most
simulate        synthetic measurements with a known truth
"""

from .dataset import DataError, Dataset, load_csv
from .effects import DEFAULT_EFFECTS, Effect, EffectError, JointEffect, parse_effects
from .error_model import ErrorModel
from .identify import Fit, error_stats, identify
from .kinematics import forward, run_chain, tool_points
from .model_loading import load_model
from .robot_model import ModelError, RobotModel, builtin_models

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
