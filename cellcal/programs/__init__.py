"""Robot programs as the controllers read them: find their targets and write them back
compensated, byte for byte elsewhere (URScript: :mod:`.urscript`; KUKA KRL ``.dat``:
:mod:`.krl`). The numbers come from :mod:`calibration.compensation.pose_compensation`
(:mod:`.compensate` joins the two)."""
