"""Capture: plans and routines, their dry run, the executor, the run store (a SQLite file
or a PostgreSQL database), the capture service and the ``cellcal`` command line.

Modules
    ``plans``           ``Plan`` and ``Target``: plans as data with a content hash
    ``check``           the dry run of a plan against the model (limits, reach, floor)
    ``routines/``       the capture routines: each makes a plan (see its package)
    ``executor``        runs a plan point by point: move, measure, commit, fault handling
    ``errors``          the capture's own errors and the service's refusals
    ``run_context``     ``RunContext`` and ``ExecutorOptions``: what a run was started with
    ``store``           ``RunStore``, ``open_store``: runs, samples, interruptions, calibrations
    ``store_records``   the store's records: ``Run``, ``Sample``, ``Samples``, ``Calibration``
    ``store_dialect``   the two databases (SQLite, PostgreSQL) behind one small interface
    ``store_schema``    the store's SQL schema and its upgrades between versions
    ``run_data``        runs as calibration inputs: a data set, zero-point postures
    ``service``         plan, start and resume runs (the commands and the demo call it)
    ``progress``        the progress line of a capture on a terminal
    ``frame_fit``       circle, line and measurement-frame fits for the frame routine
    ``demo_workflow``   the whole cell on the simulator, from capture to a better robot
    ``cli``             the ``cellcal`` parser and its exit codes
    ``commands/``       one module per ``cellcal`` sub-command (see its package)
"""
