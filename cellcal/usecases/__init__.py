"""The use cases the commands call: one module per use case, each with its typed request
(a :class:`cellcal.request.Request`, the flags as aliases) and one function that takes the
request, returns a typed result and prints nothing (progress through callbacks).

Modules (command in brackets)
    ``values``        parsing of comma-separated numbers (no heavy imports)
    ``flag_errors``   a model's validation errors reported with the user's flags
    ``capture``       [capture] plan, dry-run and run a routine into the run store
    ``resume``        [resume] continue an interrupted run
    ``runs``          [runs] the runs of a store, or one in detail
    ``export_run``    [export] a run's samples or postures as CSV
    ``zero``          [zero] joint zero offsets from 20 postures (``zero_inputs``: the
                      postures, the chain and the replayed offsets)
    ``sim_serve``     [sim serve] the simulated cell behind its wire protocols
    ``demo``          [demo] the whole workflow on the simulated cell (``demo_folder``: the
                      guard on its output folder)
"""
