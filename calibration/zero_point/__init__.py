"""Zero-point recalibration from 20 postures (5 on each of 4 planes) on one fixed point.

After a crash or a motor swap a joint's zero moves. The robot is taught, by hand,
20 postures that all put the tool tip on the same fixed target point; only the
joint readings are recorded (optionally also the tip, measured). Two methods
estimate the joint zero corrections from them (true angle = reported + offset):

- :func:`seed_method`, the published method this project was founded on, done
  faithfully: forward kinematics of each posture; least squares for the tool
  (TCP) coordinates; the target point of each posture from them; their mean as a
  virtual target; resampling around it (random candidates weighted by
  exp(-distance to the posture points), normalised, sorted, top 20 % averaged);
  the calibration equations of the postures solved for joint corrections with
  the damped pseudo-inverse ``Jᵀ(JJᵀ + kI)⁻¹``; repeated until every posture's
  tip matches the virtual target within a threshold.
- :func:`rigorous_method`: one least-squares problem in the joint offsets, the
  tool point (flange frame) and the target point (base frame), with an
  identifiability check (QR with column pivoting) that says which offsets the
  postures determine and which they cannot, uncertainties from the covariance
  and outlier postures flagged by their residual and left out.

A single fixed point leaves combinations free: joint 1's offset turns every tip
about the base z axis, which an unknown target absorbs, and the last joint's
offset turns the tool about the flange axis, which an unknown tool absorbs.
Measured tip positions (``x, y, z``) pin the target and make joint 1
identifiable.

Modules
-------
postures_io  Postures, the postures CSV (load_postures, Postures.to_csv), postures_from_dataset
postures     zero20_postures, zero20_directions: the 20 postures for a chain, target and tool
solvers      seed_method, rigorous_method, their ZeroResult, pivot_fit, DEFAULT_SIGMA_MM
assess       assess (usable or too poor, with the reasons), expected_undetermined
simulate     simulate_postures: hand-taught postures of a robot whose zeros moved

Lengths mm, angles rad; degrees only in files.
"""

from .assess import assess, expected_undetermined
from .postures import zero20_directions, zero20_postures
from .postures_io import Postures, load_postures, postures_from_dataset
from .simulate import simulate_postures
from .solvers import DEFAULT_SIGMA_MM, ZeroResult, pivot_fit, rigorous_method, seed_method

__all__ = [
    "DEFAULT_SIGMA_MM",
    "Postures",
    "ZeroResult",
    "assess",
    "expected_undetermined",
    "load_postures",
    "pivot_fit",
    "postures_from_dataset",
    "rigorous_method",
    "seed_method",
    "simulate_postures",
    "zero20_directions",
    "zero20_postures",
]
