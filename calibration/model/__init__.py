"""The nominal robot and its geometry: models, kinematics, transforms, gravity.

The built-in robot models are YAML files in ``builtin/`` (docs/formats.md §2).

Modules
-------
robot_model       RobotModel: the nominal robot from the model YAML, built-ins
model_loading     load_model: a model by name, by model YAML path or from a URDF
urdf_model        a RobotModel from the serial chain of a URDF
dh_conversion     the exact conversion of a chain given by its axes into DH
kinematics        run_chain: forward kinematics vectorised over poses, exact Jacobians
inverse           batched damped-Newton inverse kinematics (ChainFK, solve_ik)
transforms        rotations and rigid transforms on arrays; fit_rigid / fit_rotation (Kabsch)
gravity           gravity torques at every joint from the mass model
orientation_model predicted orientations of a 6-DoF target and their exact Jacobian
"""
