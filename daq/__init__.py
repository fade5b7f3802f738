"""Capture: plans and routines, their dry run, the executor, the run store (a SQLite file
or a PostgreSQL database) and the capture service. The ``cellcal`` command line that
calls it is the application's (:mod:`cellcal`).

Modules
    ``plans``           ``Plan`` and ``Target``: plans as data with a content hash; the
                        shortest visiting order and the estimated capture time
    ``sight``           the tracker's line of sight for a capture: the cell a plan is made
                        for, the points the tracker would not see
    ``check``           the dry run of a plan against the model (limits, reach, floor)
    ``planning``        plan a run: load the model, make the routine's plan for the cell,
                        dry-run it
    ``motion_guard``    the one motion check: every move before it is sent, and what the
                        robot did after it
    ``routines/``       the capture routines: each makes a plan (see its package)
    ``executor``        runs a plan point by point: move, measure, commit, fault handling
    ``remeasure``       suspect readings re-measured at the cell, while the robot is there
    ``drift_checks``    reference poses measured again during a capture (--drift-check)
    ``warm_gate``       --require-warm: a capture starts only on a robot that is warm
    ``stop_signals``    how a running capture answers Ctrl-C, SIGTERM and SIGHUP
    ``completeness``    whether a run that went through its plan measured enough of it
                        (``completed`` or ``incomplete``)
    ``errors``          the capture's own errors and the service's refusals
    ``run_context``     ``RunContext``, ``ExecutorOptions``, ``TrackerSetup``: what a run was
                        started with (and ``TrackerCheck``: what the tracker's checks found)
    ``tracker_checks``  the tracker's checks before a run: reflector, air, ready gate, two faces
    ``store/``          the run store behind one wall (see its package)
    ``run_data``        runs as calibration inputs: a data set, zero-point postures
    ``service``         plan, start and resume runs (the commands and the demo call it)
    ``run_request``     what the service is asked and answers: a capture request, its
                        planned run, how a run ended
    ``resumable``       a stored run to resume: found, its plan checked, its lease taken
    ``devices``         the devices of a run: opened from URLs, identified, checked against
                        the model
    ``cell_session``    one session at the cell: the devices reached, known, checked, held
    ``compensated_robot``  compensated motion from Python: a robot that goes where the
                        nominal targets meant

Logging: each module logs to ``logging.getLogger(__name__)`` (the service's decisions at
INFO); the package configures no handler but a ``NullHandler`` (the application does:
``cellcal -v``).
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
