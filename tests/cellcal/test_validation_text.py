"""What ``cellcal validate`` prints: the variants' names follow the controller driven."""

from presentation.validation_text import validation_lines

FIG = {"n": 4, "rms_mm": 0.03, "mean_mm": 0.02, "max_mm": 0.05, "ap_max_mm": 0.04,
       "rp_max_mm": 0.01}
SUMMARY = {"validation": {"uncompensated": FIG, "compensated": FIG, "geometric": FIG}}


def _names(robot):
    table = validation_lines(SUMMARY, 0.03, [], robot=robot)[2].splitlines()
    return [line.split("  ")[0].strip() for line in table[2:]]


def test_a_ur_controller_carries_the_deltas_in_its_calibration_conf():
    assert _names("ur-rtde://10.0.0.2") == ["as written", "compensated",
                                           "calibration.conf only"]
    assert _names(None)[2] == "calibration.conf only"


def test_an_abb_controller_has_no_calibration_conf():
    assert _names("abb://127.0.0.1:15080") == ["as written", "compensated", "geometry only"]
