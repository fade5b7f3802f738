"""Targets whose nominal joints contradict their point are refused by ``compensate``
(issue 29: joints 1.4 m away from their target were "reached" with a 1438 mm
"correction"), naming the rows and the distances; the tolerance is the user's."""

from __future__ import annotations

import numpy as np
import pytest

from calibration import load_model
from calibration.compensation.compensation import Targets
from calibration.model.inverse import ChainFK
from cellcal.errors import UsageError
from cellcal.flags.choices import JOINTS_TOLERANCE_MM
from cellcal.usecases.target_checks import check_joints_reach


def _targets(moved_mm: float) -> Targets:
    model = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))
    q = np.radians([[10, -80, 90, -100, -90, 0], [0, -90, 90, -90, -90, 0],
                    [30, -70, 80, -100, -90, 10]])
    p = ChainFK.from_model(model).point(q)
    p[1, 0] += moved_mm
    return model, Targets(p, q, ["a", "b", "c"], {}, [2, 3, 4])


def test_joints_that_do_not_reach_their_point_are_refused_naming_rows_and_distances():
    model, t = _targets(0.5)
    check_joints_reach(t, model, JOINTS_TOLERANCE_MM, "t.csv")  # rounding: accepted
    model, t = _targets(1438.0)
    with pytest.raises(UsageError, match=r"t\.csv: the joints q1\.\.q6 of 1 of 3 targets .*"
                       r"line 3 \(pose_id b\): 1438\.0 mm.*--joints-tolerance-mm"):
        check_joints_reach(t, model, JOINTS_TOLERANCE_MM, "t.csv")
    check_joints_reach(t, model, 2000.0, "t.csv")  # the user's tolerance
    check_joints_reach(Targets(t.base_p_tcp, None, t.pose_id, {}), model, 1.0, "t.csv")
