"""Compensation: the targets and joints that make the real robot reach where it should.

Modules
-------
compensation      compensated joints and corrected targets from a calibration
pose_compensation a program's targets compensated: full TCP poses and joint targets, batched
controller_joints the joints a controller ends at: as written, compensated, or with its own model
"""
