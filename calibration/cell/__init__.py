"""The cell around the robot: the cell YAML, the tracker's line of sight, the frame fits.

Modules
-------
cell        CellSpec: the cell YAML (tracker position, SMR axis and reflector, fixtures)
visibility  the tracker's line of sight: facing angle, link capsules, fixtures, facing IK
sight_cause why no pose is visible: the SMR inside the wrist, the constraint hiding most
frame_fit   circle, line and measurement-frame fits of the frame routine
"""
