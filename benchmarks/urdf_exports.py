"""URDF models and exports: identification round trips and export parity, as tables.

Round trip: a simulated robot with hidden geometric, base and tool errors (all parameters
perturbed), 300 calibration + 1 000 validation poses, tracker sigma 0.015 mm per axis;
the table gives the validation RMS against the noise floor sqrt(3)*sigma. Parity: each
export of the calibrated model is written, read back by its own reader and compared with
cellcal's calibrated model at 1 000 random joint sets (max tool-point distance, max
flange-orientation angle). The URDFs are written from published DH/MDH tables by the
test suite's writers (turned link frames, fixed joints, inertials).

    python benchmarks/urdf_exports.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calibration import ErrorModel, identify, load_model  # noqa: E402
from calibration.exports.controller_export import (  # noqa: E402
    ur_conf_parity,
    write_table_csv,
    write_ur_kinematics_yaml,
)
from calibration.exports.model_export import calibrated_model, write_ur_conf  # noqa: E402
from calibration.exports.urdf_export import write_urdf  # noqa: E402
from calibration.fit.simulate import random_joints, realistic_truth, simulate  # noqa: E402
from tests.calibration.urdf_writers import dh_chain_urdf, rot, ur_style_urdf  # noqa: E402

SIGMA = 0.015


def specs(tmp: Path) -> dict[str, str]:
    ur, panda = load_model("ur10e"), load_model("panda")
    rows = [j.model_dump() for j in panda.joints]
    track = [{"type": "prismatic", "a": 0.0, "alpha": 0.0, "d": 150.0, "theta_offset": 0.0,
              "min": -500.0, "max": 1500.0}] + [j.model_dump() for j in ur.joints]
    masses = [(40.0, (0.0, 0.0, -60.0))] + [(l.mass_kg, l.com) for l in ur.links]
    return {
        "ur10e (built-in)": "ur10e",
        "ur10e URDF, base_link:tool0": f"{ur_style_urdf(tmp / 'ur.urdf', ur)}#base_link:tool0",
        "rv16 (built-in, MDH)": "rv16",
        "panda (built-in, 7 axes)": "panda",
        "panda URDF (7 axes)": str(dh_chain_urdf(tmp / "panda.urdf", "mdh", rows,
                                                 tool=panda.tool, split_fixed=True,
                                                 rng=np.random.default_rng(5))),
        "track + ur10e URDF (P + 6R)": str(dh_chain_urdf(
            tmp / "track.urdf", "dh", track, masses=masses, rng=np.random.default_rng(8),
            mount=rot("y", np.pi / 2), tool=(0.0, 0.0, 60.0))),
    }


def round_trip(spec: str, seed: int = 1):
    m = load_model(spec)
    em = ErrorModel(m)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    q = random_joints(m, 1300, rng)
    data = simulate(em, x, q, SIGMA, rng, is_valid=np.arange(1300) >= 300)
    fit = identify(em, data)
    return m, em, x, fit, data.noise_floor_mm()


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        print(f"round trip: 300 calibration + 1000 validation poses, sigma {SIGMA} mm/axis, "
              "all parameters perturbed")
        print(f"{'model':<30} {'joints':>6} {'params':>6} {'ident.':>6} {'valid RMS mm':>12} "
              f"{'floor mm':>9} {'ratio':>6}")
        parity_rows = []
        for label, spec in specs(tmp).items():
            m, em, x, fit, floor = round_trip(spec)
            print(f"{label:<30} {m.n_joints:>6} {em.n_params:>6} {int(fit.free.sum()):>6} "
                  f"{fit.valid['rms_mm']:>12.4f} {floor:>9.4f} "
                  f"{fit.valid['rms_mm'] / floor:>6.3f}")
            model, notes = calibrated_model(em, fit.values)
            parity_rows.append((label, "URDF", write_urdf(model, tmp / "cal.urdf", notes)))
            parity_rows.append((label, "DH/MDH CSV", write_table_csv(model, tmp / "t.csv")))
            if m.n_joints == 6 and m.convention == "dh":
                parity_rows.append((label, "UR kinematics YAML",
                                    write_ur_kinematics_yaml(model, tmp / "k.yaml")))
                write_ur_conf(em, fit.values, tmp / "calibration.conf")
                parity_rows.append((label, "UR calibration.conf",
                                    ur_conf_parity(tmp / "calibration.conf", model, m)))
        print()
        print("export parity: the file read back vs cellcal's calibrated model, 1000 joint sets")
        print(f"{'model':<30} {'export':<20} {'reader':<32} {'max mm':>9} {'max rad':>9}")
        for label, what, p in parity_rows:
            print(f"{label:<30} {what:<20} {p.reader:<32} {p.max_mm:>9.1e} {p.max_rad:>9.1e}")


if __name__ == "__main__":
    main()
