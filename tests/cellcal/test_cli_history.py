"""``cellcal calibrate --db --robot-id`` records calibrations, ``cellcal history`` reads them:
on both backends (a SQLite file and a PostgreSQL database)."""

from __future__ import annotations

import json
import math

import pytest

from cellcal.cli import main
from daq.store import RunStore
from tests.daq.test_store import _at_version


def _params(values: dict, std: float = 0.1) -> dict:
    return {"model": "ur10e", "effects": ["geometric", "base", "tool"],
            "stats": {"calib": {"rms_mm": 0.02}},
            "parameters": [{"name": n, "value": v, "std": None if n == "fixed" else std,
                            "unit": "deg" if n.endswith("theta") else "mm",
                            "identifiable": n != "fixed"} for n, v in values.items()]}


@pytest.fixture
def history_store(store_address):
    s2 = math.sqrt(2) * 0.1  # the combined sigma of two calibrations with std 0.1
    with RunStore(store_address) as st:
        for k, (theta, d) in enumerate([(0.0, 1.0), (2.9 * s2, 1.0), (2.9 * s2 + 3.1 * s2, 1.1),
                                        (2.9 * s2 + 3.1 * s2, 1.2)]):
            st.add_calibration("R7", _params({"geometric.j2.theta": theta, "geometric.j2.d": d,
                                              "fixed": 0.0}),
                               t=1.7e9 + k * 86400.0, source_file=f"/data/cal{k}.csv")
        st.add_calibration("other", _params({"geometric.j2.theta": 5.0}), t=1.0)
    return store_address


def test_history_flags_changes_beyond_three_combined_sigma(history_store, tmp_path, capsys):
    assert main(["history", "R7", "--db", history_store, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["robot_id"] == "R7" and out["threshold_sigma"] == 3.0
    assert [c["source_file"] for c in out["calibrations"]] == [f"/data/cal{k}.csv"
                                                              for k in range(4)]
    assert out["calibrations"][0]["time"] == "2023-11-14T22:13:20Z"
    assert out["calibrations"][0]["effects"] == ["geometric", "base", "tool"]
    (flag,) = out["flagged"]
    ids = [c["id"] for c in out["calibrations"]]
    assert flag["parameter"] == "geometric.j2.theta" and (flag["from"], flag["to"]) == \
        (ids[1], ids[2])
    assert flag["z"] == pytest.approx(3.1) and flag["sigma"] == pytest.approx(math.sqrt(2) * 0.1)
    theta, d, fixed = out["parameters"]
    assert [c["flagged"] for c in theta["changes"]] == [False, True, False]
    assert theta["changes"][0]["z"] == pytest.approx(2.9)
    assert [v["value"] for v in d["values"]] == [1.0, 1.0, 1.1, 1.2] and d["unit"] == "mm"
    assert fixed["values"][0]["std"] is None and fixed["changes"][0]["z"] is None

    plot = tmp_path / "h.html"
    assert main(["history", "R7", "--db", history_store, "--plot", str(plot)]) == 0
    text = capsys.readouterr().out
    assert "1 change(s) larger than 3 combined sigma" in text
    assert "geometric.j2.theta: calibration" in text and "3.1 sigma" in text
    assert "held fixed, not identifiable: fixed" in text
    assert "\ngeometric.j2.theta (deg)\n" in text  # the flagged one in detail, by default
    assert "\ngeometric.j2.d (mm)\n" not in text
    assert plot.read_text().startswith("<!DOCTYPE html>") and "data:image/png" in plot.read_text()
    png = tmp_path / "h.png"
    assert main(["history", "R7", "--db", history_store, "--param", "*.d", "--sigma", "2.5",
                 "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "2 change(s) larger than 2.5 combined sigma" in text
    assert "\ngeometric.j2.d (mm)\n" in text and "\ngeometric.j2.theta (deg)\n" not in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_history_refuses_unknown_robots_and_bad_flags(history_store, tmp_path, capsys):
    assert main(["history", "R8", "--db", history_store]) == 2
    assert "no calibrations of robot 'R8' (robots with calibrations: R7, other)" in \
        capsys.readouterr().err
    assert main(["history", "R7", "--db", history_store, "--plot", "x.pdf"]) == 2
    assert main(["history", "R7", "--db", history_store, "--param", "nothing*"]) == 2
    with pytest.raises(SystemExit) as e:  # refused by the parser: a positive number
        main(["history", "R7", "--db", history_store, "--sigma", "0"])
    assert e.value.code == 2
    capsys.readouterr()
    old = str(tmp_path / "old.db")
    _at_version(old, 3)
    assert main(["history", "R7", "--db", old]) == 2  # read in a copy upgraded in memory
    assert "no calibrations of robot 'R7' (robots with calibrations: none)" in \
        capsys.readouterr().err
    assert main(["history", "R7", "--db", str(tmp_path / "missing.db")]) == 2


def test_calibrate_records_the_calibration(store_address, tmp_path, capsys):
    csv = tmp_path / "cal.csv"
    assert main(["simulate", "--model", "ur10e", "--poses", "80", "--valid", "0", "--seed", "4",
                 "--out", str(csv)]) == 0
    capsys.readouterr()
    args = ["calibrate", str(csv), "--model", "ur10e", "--db", store_address, "--json"]
    assert main(args) == 2  # which robot?
    assert "give --robot-id" in capsys.readouterr().err
    assert main([*args, "--robot-id", "R1"]) == 0
    first = json.loads(capsys.readouterr().out)["calibration"]
    assert first["robot_id"] == "R1" and first["new"] is True
    assert main([*args, "--robot-id", "R1"]) == 0  # the same fit again: recorded once
    assert json.loads(capsys.readouterr().out)["calibration"] == {**first, "new": False}
    # data exported from a run name their robot (and run)
    lines = csv.read_text().splitlines(keepends=True)
    tagged = tmp_path / "tagged.csv"
    tagged.write_text("# run: 1\n# plan_hash: abc\n# robot_id: cell-3/UR10e\n" + "".join(lines))
    assert main(["calibrate", str(tagged), "--model", "ur10e", "--db", store_address]) == 0
    assert "recorded as calibration" in capsys.readouterr().out
    with RunStore(store_address) as st:
        (cal,) = st.calibrations("cell-3/UR10e")
        (r1,) = st.calibrations("R1")
    assert cal.source_file == str(tagged.resolve()) and cal.source_run is None  # no such run
    assert cal.params["effects"] == ["geometric", "base", "tool"] and r1.id == first["id"]
    assert main(["calibrate", str(csv), "--model", "ur10e", "--robot-id", "R1"]) == 2
