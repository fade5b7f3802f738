"""A calibration written out: params.json, model YAML, controller files, URDF, with parity.

Modules
-------
params_io         params.json: a fit's parameters written and read back
model_export      the calibrated model as model YAML and UR calibration.conf deltas
controller_export controller-side exports, each read back and checked for parity
urdf_export       a calibrated model as a URDF, with the parity check through yourdfpy
ur_conf           UR calibration.conf deltas and the exact conversion to pure DH
parity            parity checks of exported kinematics against the model
"""
