"""Identification: an error model fitted to measured poses, and what the fit knows.

Modules
-------
error_model           ErrorModel: a model plus effects; perturb (the one apply chain), evaluate
identify              identify -> Fit (values, uncertainties, residuals, statistics), fit_at
full_pose             what identification adds when the data carry orientations
identifiability       which parameters a data set determines (QR with column pivoting)
solvers/              lm, ridge, besa, sa: the least-squares solvers identify uses
outliers              blunders found, named and left out
leverage              how much of each residual the fit absorbed; leave-one-out residuals
uncertainty           correlations, Monte-Carlo re-identification, position uncertainty
orientation_residuals orientation residuals of a 6-DoF target, weighted by their uncertainty
data_quality          data too poor to identify a model: refused (InsufficientData), not fitted
model_check           a given model's error on new poses, as calibrated (only the base refitted)
thermal_state         the thermal state of a calibration and of a compensation
envelope              the calibrated envelope (what lies beyond it); tables over their
                      supported knots (identify_supported)
simulate              synthetic measurements with a known truth
"""
