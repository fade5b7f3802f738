"""cellcal's presentation layer: what the calibration core's results look like to a person.

Figures, the HTML report and the command line's JSON objects; it imports the calibration
core only (never daq, drivers or sim_drivers), and the core never imports it. Importing
this package loads nothing else: matplotlib comes with the modules that draw.

Modules
-------
html_report  build_report / render_report: the self-contained HTML page (Report, ReportError)
html_tables  the report's tables (statistics, steps, blunders, candidates, parameters), style
figures      the report's figures of the whole story (RMS by stage and by step, histograms,
             workspace, error over the capture, periodogram)
thermal_figures  the thermal state in the report: a drift effect's x axis, the residual
             against each joint's temperature
joint_figures  the residual seen from each joint, and each auto step's before/after
plot_base    what the figures share: style, Stage, deterministic PNGs, binned medians
residual_points  the poses as a fit sees them (joint-equivalent residual, lever arm, torque)
provenance   Provenance: software, date, data file and SHA-256, run id, model
ridge_plot   plot_ridge: L-curve, GCV and ridge trace of a ridge fit
summaries    fit_summary, calibration_summary (calibrate --json), diagnosis_summary
             (diagnose --json), zero_summary (zero --json)
orientation_figures  the report's orientation section: residual per pose and per joint
history_plot  history --plot: each parameter's value over time with its sigma bars
plan_figure  plan_figure: a capture plan with the robot, the tracker and the beams
text_table   table, fmt: plain-text tables and numbers for the command line
calibration_text   calibrate's text; tool_text, blunder_lines (shared with diagnose)
orientation_text   calibrate's orientation lines (data of a 6-DoF target)
diagnosis_text     diagnose's ranking, and the steps of diagnose --auto
report_summary     what report prints about the page (text, --json)
compensation_text  compensate's CSV, text, export lines and --json object
thermal_text       the thermal state a compensation was made for, in words
program_text       compensate --program's report: program_lines, program_summary (--json)
validation_text    validate's waypoint errors and the --json keys it adds
run_listing        runs: the rows of the list, and one run in detail
run_outcome        how a capture run ended (capture, resume): its lines, its exit code
zero_text          zero's text: postures, convergence, a row per joint, the verdict
demo_text          the demo's closing table: validation RMS stage by stage
history_text       history's tables and --json object (and the checks: accuracy over time)
check_text         check's text and --json object: a calibration's error on new poses
simulation_text    the line simulate prints
models_text        the table of built-in models
"""
