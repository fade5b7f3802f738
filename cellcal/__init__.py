"""The cellcal application: the ``cellcal`` command line, one thin module per command,
the demo, and the use-case functions the commands call.

It imports every layer below it (``calibration``, ``drivers``, ``sim_drivers``, ``daq``,
``presentation``); nothing imports it. ARCHITECTURE.md maps the layers.

Modules
    ``cli``             the ``cellcal`` parser, its error-to-exit-code mapping
    ``commands/``       one module per ``cellcal`` sub-command (see its package)
    ``usecases/``       one module per use case: its typed request and its function (the
                        demo's whole cell on the simulator among them)
    ``flags/``          the flags' vocabulary the parser and the requests share (see its
                        package)
    ``programs/``       robot programs: their targets found and written back compensated
    ``errors``          ``UsageError``: bad usage of a command (exit 2)
    ``progress``        the progress line of a capture on a terminal
    ``logs``            logging set up once per command; the log a capture keeps by its run
    ``request``         typed requests: what a command was asked, naming the user's flags
    ``url_schemes``     the URL schemes the application adds to the drivers' (``sim://``)
"""
