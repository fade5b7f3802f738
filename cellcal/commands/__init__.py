"""The ``cellcal`` sub-commands: each declares its flags, builds one typed request from
them (:mod:`cellcal.request`), calls one use-case function (:mod:`cellcal.usecases`) and
prints what :mod:`presentation` makes of its result; none passes the argparse namespace
beyond its request. The flags' vocabulary (defaults, choices, flag tables) is
:mod:`cellcal.flags`, shared with the requests.

Modules (sub-command in brackets)
    ``common``            shared helpers: the argparse types of numbers, shared options,
                          printing; the guard on outputs and opening a store (from
                          :mod:`cellcal.usecases`)
    ``parsers``           the help formatter, sub-command parsers and command groups
    ``demo``              [demo] the whole workflow on the simulated cell
    ``capture``           [capture ROUTINE] plan, dry-run and run a routine into the store
    ``motion_prompt``     asking before anything moves (capture, resume)
    ``run_outcome``       the progress line and the printed outcome of a run (capture, resume)
    ``runs``              [runs] list the runs of a store, or show one
    ``resume``            [resume] continue an interrupted run
    ``export_run``        [export] a run's samples as a measurement or postures CSV
    ``calibrate``         [calibrate] identify a model's errors from a measurement CSV
    ``check``             [check] a calibration's error on new poses, as calibrated
    ``history``           [history] a robot's calibrations over time
    ``diagnose``          [diagnose] rank the effects missing from a calibrated model
    ``models``            [models] list the built-in robot models
    ``sim_serve``         [sim serve] serve the simulated cell over its wire protocols
    ``simulate_dataset``  [simulate] write a measurement CSV of a simulated robot
    ``zero``              [zero] zero-point recalibration from 20 postures
    ``report``            [report] the HTML calibration report
    ``compensate``        [compensate] joints and corrected targets from a calibration
    ``compensate_program`` [compensate --program] a robot program compensated
    ``validate``          [validate] a program's waypoints run as written and compensated
"""
