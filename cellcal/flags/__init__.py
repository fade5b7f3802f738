"""The command line's vocabulary, shared by the parser (``cellcal.commands``) and the typed
requests (``cellcal.usecases``): defaults and choices, flag tables, number lists. Free of
heavy imports (the parser is built from it at start-up).

Modules
    ``choices``        the parser's defaults and choices (equal to the core's, import-free)
    ``capture_flags``  the flags capture and resume share (store, devices, executor, tracker)
    ``routine_args``   the command-line options of each capture routine
    ``program_flags``  the flags of a robot program (compensate --program, validate)
    ``sim_ports``      the simulated cell's default ports and their flags
    ``values``         comma-separated numbers
    ``log_flags``      the logging flags every command takes (-v, --log-level, --log-file)
"""
