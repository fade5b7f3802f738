"""Diagnosis: where a fitted model fails and which missing physical effect explains it.

Modules
-------
diagnosis             diagnose: residual patterns and the candidate effects ranked
auto_diagnosis        add the best missing effect, refit, repeat while the held-out error falls
screening             candidates screened at a linearised fit
linear_screen         the linearised fit and the screening formulas
candidate_columns     a candidate effect's Jacobian columns at a fit
table_screening       a correction table as a candidate: knot spacing and smoothing by GCV
f_test                the F-test of a candidate effect
orientation_view      where a fit's orientations fail: per flange axis and per joint
orientation_blindness where a position-only calibration cannot check the tool orientation
history               a robot's calibration history: each parameter over time
"""
