"""The use cases of the ``cellcal`` commands: for each command a typed request (a
:class:`cellcal.request.Request`, its fields named by the flags) and one function that
does the work and returns a typed result; the command module parses, calls it and prints
what :mod:`presentation` makes of the result. A use-case function prints nothing (its
remarks are returned as notes) and raises the layers' errors (UsageError, the core's
input errors, InsufficientData).

Imported inside a command's ``run`` (they import pydantic and the calibration core; the
parser's start-up stays fast), except :mod:`.outputs` and :mod:`.stores`, which import
nothing heavy at load.

Modules
-------
inputs              the measurement CSV, its model and the current model: request fields
                    and loaders (calibrate, diagnose, report)
outputs             check_outputs: the guard on output paths; existing_paths
stores              open_store: an existing run store, or a UsageError naming it
calibrate           CalibrateRequest, calibrate: identify the error parameters
calibration_record  calibrate --db: record a calibration in a run store
diagnose            DiagnoseRequest, diagnose: rank the missing effects, or add them (--auto)
report              ReportRequest, write_report: the HTML report
compensate          CompensateRequest, compensate_targets: joints and corrected targets
model_exports       write_exports: the calibrated model as YAML, URDF, UR files, DH table,
                    each checked by its parity
simulate            SimulateRequest, simulate_dataset: a measurement CSV of a simulated robot
models              builtin_model_summaries: the built-in robot models
history             HistoryRequest, robot_history: a robot's calibrations over time
"""
