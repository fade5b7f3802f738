"""Layer rules, checked on what a fresh interpreter actually imports: the calibration core
loads no plotting and no other cellcal package; presentation loads only the core."""

import json
import subprocess
import sys

_PROBE = """
import importlib, json, pkgutil, sys
pkg = importlib.import_module({package!r})
names = [m.name for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + ".")]
for name in names:
    importlib.import_module(name)
print(json.dumps({{"modules": names, "loaded": sorted(sys.modules)}}))
"""

OTHER_PACKAGES = ("cellcal", "daq", "drivers", "sim_drivers", "presentation")


def _import_all(package: str) -> dict:
    out = subprocess.run([sys.executable, "-c", _PROBE.format(package=package)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def _top(loaded: list[str]) -> set[str]:
    return {m.split(".")[0] for m in loaded}


def test_calibration_imports_no_matplotlib_and_no_other_layer():
    doc = _import_all("calibration")
    assert "calibration.workflow" in doc["modules"] and "calibration.zero_point.solvers" in \
        doc["modules"]
    top = _top(doc["loaded"])
    assert "matplotlib" not in top
    assert not top & set(OTHER_PACKAGES)


def test_presentation_imports_the_core_only():
    doc = _import_all("presentation")
    assert {"presentation.html_report", "presentation.figures", "presentation.ridge_plot",
            "presentation.summaries"} <= set(doc["modules"])
    top = _top(doc["loaded"])
    assert "calibration" in top
    assert not top & {"cellcal", "daq", "drivers", "sim_drivers"}
