"""cellcal's presentation layer: what the calibration core's results look like to a person.

Figures, the HTML report and the command line's JSON objects; it imports the calibration
core only (never daq, drivers or sim_drivers), and the core never imports it. Importing
this package loads nothing else: matplotlib comes with the modules that draw.

Modules
-------
html_report  build_report / render_report: the self-contained HTML page (Report, ReportError)
figures      the report's matplotlib figures (Agg canvases, deterministic PNGs), Stage
ridge_plot   plot_ridge: L-curve, GCV and ridge trace of a ridge fit
summaries    fit_summary (calibrate --json), zero_summary (zero --json)
plan_figure  plan_figure: a capture plan with the robot, the tracker and the beams
"""
