"""The use cases of the ``cellcal`` commands: for each command a typed request (a
:class:`cellcal.request.Request`, its fields named by the flags) and one function that
does the work and returns a typed result; the command module parses, calls it and prints
what :mod:`presentation` makes of the result. A use-case function prints nothing (its
remarks are returned as notes, or passed to a callback as they come; progress
likewise) and raises the layers' errors (UsageError, the core's
input errors, InsufficientData).

Imported inside a command's ``run`` (they import pydantic and the calibration core; the
parser's start-up stays fast), except :mod:`.outputs` and :mod:`.stores`, which import
nothing heavy at load.

Modules
-------
input_errors        wrap_errors: a reader's input error as a usage error (light at import)
inputs              the measurement CSV, its model and the current model: request fields
                    and loaders (calibrate, diagnose, report)
outputs             check_outputs: the guard on output paths; existing_paths
stores              open_store: an existing run store, or a UsageError naming it
calibrate           CalibrateRequest, calibrate: identify the error parameters
calibration_record  calibrate --db: record a calibration in a run store
check               CheckRequest, check: a calibration's error on new poses, as calibrated
diagnose            DiagnoseRequest, diagnose: rank the missing effects, or add them (--auto)
report              ReportRequest, write_report: the HTML report
compensate          CompensateRequest, compensate_targets: joints and corrected targets
compensate_program  ProgramRequest, compensate_program: a robot program compensated
program_inputs      a program's frames (--frames) and filter options, checked by their flags
target_checks       check_joints_reach: targets whose joints contradict their point
model_exports       write_exports: the calibrated model as YAML, URDF, UR files, DH table,
                    each checked by its parity
simulate            SimulateRequest, simulate_dataset: a measurement CSV of a simulated robot
models              builtin_model_summaries: the built-in robot models
history             HistoryRequest, robot_history: a robot's calibrations over time
flag_errors         a model's validation errors reported with the user's flags
capture             [capture] plan, dry-run and run a routine into the run store
resume              [resume] continue an interrupted run
runs                [runs] the runs of a store, or one in detail
export_run          [export] a run's samples or postures as CSV
zero                [zero] joint zero offsets from 20 postures
zero_inputs         the zero-point recalibration's inputs: the postures, the chain, the
                    joints, the replayed offsets
sim_serve           [sim serve] the simulated cell behind its wire protocols
validate            [validate] a program's waypoints run as written and compensated
demo                [demo] the whole workflow on the simulated cell
demo_folder         the guard on the demo's output folder (its manifest, demo.json)
demo_cold_start     the demo's cold start: the robot warms up while it is captured
"""
