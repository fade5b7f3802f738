"""The ``cellcal`` sub-commands: each parses its arguments, calls the layer below with typed
inputs and prints; none passes the argparse namespace on. calibrate, diagnose, report,
compensate, simulate, models and history build a typed request, call one use-case
function (:mod:`cellcal.usecases`) and print what :mod:`presentation` makes of its result.

Modules (sub-command in brackets)
    ``common``            shared helpers: the argparse types of numbers, shared options,
                          printing; the guard on outputs and opening a store (from
                          :mod:`cellcal.usecases`)
    ``choices``           the parser's defaults and choices (equal to the core's, import-free)
    ``demo``              [demo] the whole workflow on the simulated cell
    ``capture``           [capture ROUTINE] plan, dry-run and run a routine into the store
    ``routine_args``      the command-line options of each capture routine
    ``capture_flags``     the flags capture and resume share (store, devices, executor, tracker)
    ``motion_prompt``     asking before anything moves (capture, resume)
    ``run_outcome``       the progress line and the printed outcome of a run (capture, resume)
    ``runs``              [runs] list the runs of a store, or show one
    ``resume``            [resume] continue an interrupted run
    ``export_run``        [export] a run's samples as a measurement or postures CSV
    ``calibrate``         [calibrate] identify a model's errors from a measurement CSV
    ``diagnose``          [diagnose] rank the effects missing from a calibrated model
    ``models``            [models] list the built-in robot models
    ``sim_serve``         [sim serve] serve the simulated cell over its wire protocols
    ``simulate_dataset``  [simulate] write a measurement CSV of a simulated robot
    ``zero``              [zero] zero-point recalibration from 20 postures
    ``report``            [report] the HTML calibration report
    ``compensate``        [compensate] joints and corrected targets from a calibration
"""
