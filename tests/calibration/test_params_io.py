import json

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.exports.params_io import ParamsError, fit_to_dict, load_params, save_params
from calibration.fit.simulate import random_joints, realistic_truth, simulate


def test_params_round_trip(tmp_path):
    m = load_model("ur5e")
    em = ErrorModel(m)
    rng = np.random.default_rng(0)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 100, rng), 0.02, rng)
    fit = identify(em, data)
    p = tmp_path / "params.json"
    save_params(fit, p)
    doc = json.loads(p.read_text())
    row = next(r for r in doc["parameters"] if r["name"] == "geometric.j2.alpha")
    assert row["unit"] == "deg"
    em2, x, std = load_params(p)
    assert em2.names == em.names and em2.model == m
    np.testing.assert_allclose(x, fit.values, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(std, fit.std, rtol=1e-12, atol=1e-15)
    # the loaded parameters predict what the fit predicts
    np.testing.assert_allclose(em2.evaluate(x, em2.bind(data), False)[0], fit.predict(data))


def test_bad_params_files(tmp_path):
    p = tmp_path / "p.json"
    p.write_text("{not json")
    with pytest.raises(ParamsError, match="not valid JSON"):
        load_params(p)
    p.write_text('{"format": "other"}')
    with pytest.raises(ParamsError, match="not a cellcal params file"):
        load_params(p)
    m = load_model("ur5e")
    em = ErrorModel(m)
    rng = np.random.default_rng(0)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 60, rng), 0.02, rng)
    doc = fit_to_dict(identify(em, data))
    doc["parameters"][0]["unit"] = "rad"
    p.write_text(json.dumps(doc))
    with pytest.raises(ParamsError, match="unit 'rad', expected 'deg'"):
        load_params(p)


def test_auto_steps_are_recorded_and_read_back(tmp_path):
    """``diagnose --auto --out``'s steps ride along in params.json; the parameters read as
    before, and a file without them (``calibrate``) has none."""
    from calibration.diagnosis.auto_diagnosis import auto_diagnose
    from calibration.exports.params_io import read_auto_steps

    m = load_model("ur5e")
    em = ErrorModel(m, "geometric,base,tool,compliance:3")
    rng = np.random.default_rng(3)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 200, rng), 0.015, rng)
    start = identify(ErrorModel(m), data)
    auto = auto_diagnose(start, data, max_steps=2)
    assert [s.effect for s in auto.steps][:1] == ["compliance:3"]
    p = tmp_path / "auto.json"
    save_params(auto.fit, p, auto=auto)
    rec = read_auto_steps(p)
    assert rec["start_effects"] == ["geometric", "base", "tool"]
    assert [s["effect"] for s in rec["steps"]] == [s.effect for s in auto.steps]
    assert rec["steps"][0] == auto.steps[0].to_json()
    assert rec["stop_reason"] == auto.stop_reason
    assert rec["start_heldout_rms_mm"] == pytest.approx(auto.start_heldout_rms_mm)
    em2, x, _ = load_params(p)
    assert em2.labels == auto.effects
    np.testing.assert_allclose(x, auto.fit.values, rtol=1e-12, atol=1e-12)
    plain = tmp_path / "plain.json"
    save_params(start, plain)
    assert read_auto_steps(plain) is None and read_auto_steps({"auto_steps": 3}) is None
# ---- version 2: strict values, model checks, effect files only on request ----------------
EFFECT = '''import numpy as np
from calibration.effects import JointEffect


class SinTwo(JointEffect):
    family = "sintwo"
    summary = "a twice-per-turn joint error"

    def __init__(self, model, joint=None, order=None):
        super().__init__(model, joint, order)
        self.param_names, self.units, self.scales = ["amp"], ["rad"], np.array([1e-4])

    def delta(self, p, data, state):
        s = np.sin(2 * data.q[:, self.joint - 1])
        return p[0] * s, s[:, None]
'''


@pytest.fixture(scope="module")
def fitted():
    m = load_model("ur5e")
    em = ErrorModel(m)
    rng = np.random.default_rng(1)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 60, rng), 0.02, rng)
    return identify(em, data)


def _doc(fit):
    return json.loads(json.dumps(fit_to_dict(fit), default=float))


def test_version_2_records_the_model_hash_and_weak_parameters(fitted, tmp_path):
    p = tmp_path / "p.json"
    save_params(fitted, p)
    doc = json.loads(p.read_text())
    assert doc["version"] == 2
    assert doc["model_hash"] == load_model("ur5e").definition_hash()
    assert all("weak" in r for r in doc["parameters"])
    assert set(doc["weakly_identified"]) == {r["name"] for r in doc["parameters"] if r["weak"]}
    assert "NaN" not in p.read_text() and "Infinity" not in p.read_text()


def test_version_1_files_still_load(fitted, tmp_path):
    doc = _doc(fitted)
    doc["version"] = 1
    for k in ("model_hash", "weakly_identified"):
        doc.pop(k)
    for r in doc["parameters"]:
        r.pop("weak")
    doc["effect_files"] = []
    p = tmp_path / "v1.json"
    p.write_text(json.dumps(doc))
    em, x, _ = load_params(p)
    np.testing.assert_allclose(x, fitted.values, atol=1e-12)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["parameters"][3].__setitem__("value", float("nan")), "parameters.3.value"),
    (lambda d: d["parameters"][3].__setitem__("value", None), "parameters.3.value"),
    (lambda d: d["parameters"][3].pop("value"), "parameters.3.value: missing"),
    (lambda d: d["parameters"][3].__setitem__("value", "0.5"), "is not a number"),
    (lambda d: d["parameters"][3].__setitem__("value", 1e300), "plausible"),
    (lambda d: d["parameters"][3].__setitem__("std", -1.0), "std"),
    (lambda d: d.pop("parameters"), "parameters: missing"),
    (lambda d: d.__setitem__("version", 3), "newer"),
    (lambda d: d["model_definition"]["joints"][1].__setitem__("a", -400.0), "model_hash"),
    (lambda d: d["model_definition"]["joints"][1].__setitem__("a", float("inf")),
     "model_definition"),
])
def test_bad_values_are_refused_naming_the_field(fitted, tmp_path, edit, message):
    doc = _doc(fitted)
    edit(doc)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(ParamsError, match=message) as e:
        load_params(p)
    assert "\n" not in str(e.value) and str(p) in str(e.value)


def test_params_of_another_model_are_refused(fitted, tmp_path):
    p = tmp_path / "p.json"
    save_params(fitted, p)
    with pytest.raises(ParamsError, match="ur5e.*joints.*ur10e"):
        load_params(p, model=load_model("ur10e"))
    # the same joints, another tool: used, with a note
    from calibration.exports.params_io import read_params

    other = load_model("ur5e").with_changes(tool=(0.0, 0.0, 60.0))
    loaded = read_params(p, model=other)
    assert loaded.notes and "tool" in loaded.notes[0]


def test_effect_files_run_only_when_given_and_unchanged(tmp_path):
    from calibration import effects
    from calibration.effects import load_effect_file
    from calibration.exports.params_io import read_params

    registry = dict(effects.REGISTRY)
    try:
        f = tmp_path / "sintwo.py"
        f.write_text(EFFECT)
        load_effect_file(f)
        m = load_model("ur5e")
        em = ErrorModel(m, "geometric,base,tool,sintwo:2")
        rng = np.random.default_rng(2)
        data = simulate(em, realistic_truth(em, rng), random_joints(m, 80, rng), 0.02, rng)
        p = tmp_path / "p.json"
        save_params(identify(em, data), p)
        rec = json.loads(p.read_text())["effect_files"]
        assert rec == [{"name": "sintwo.py", "sha256": effects.effect_source(
            effects.REGISTRY["sintwo"])[1], "families": ["sintwo"]}]
        assert read_params(p).error_model.labels[-1] == "sintwo:2"
        # a fresh process: the family is unknown until the user names the file
        effects.REGISTRY.clear()
        effects.REGISTRY.update(registry)
        with pytest.raises(ParamsError, match="--effect-file sintwo.py"):
            read_params(p)
        f.write_text(EFFECT + "# edited\n")
        load_effect_file(f)
        with pytest.raises(ParamsError, match="changed since the calibration"):
            read_params(p)
    finally:
        effects.REGISTRY.clear()
        effects.REGISTRY.update(registry)


def test_a_path_in_a_params_file_never_runs(fitted, tmp_path):
    (tmp_path / "evil.py").write_text(
        "from pathlib import Path\nPath(__file__).with_name('PWNED').write_text('x')\n")
    doc = _doc(fitted)
    doc["effect_files"] = [str(tmp_path / "evil.py")]  # the version-1 form: a path
    p = tmp_path / "p.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(ParamsError, match="--effect-file evil.py"):
        load_params(p)
    assert not (tmp_path / "PWNED").exists()


def test_a_user_effect_replaces_a_builtin_only_when_it_says_so(tmp_path):
    from calibration import effects
    from calibration.effects import EffectError, load_effect_file

    registry = dict(effects.REGISTRY)
    body = ("from calibration.effects.geometric import Tool\n\n"
            "class MyTool(Tool):\n    family = 'tool'\n")
    try:
        f = tmp_path / "mytool.py"
        f.write_text(body)
        with pytest.raises(EffectError, match="built-in.*replaces_builtin"):
            load_effect_file(f)
        assert effects.REGISTRY["tool"] is registry["tool"]
        f.write_text(body + "    replaces_builtin = True\n")
        load_effect_file(f)
        assert effects.REGISTRY["tool"].__name__ == "MyTool"
        assert not (tmp_path / "__pycache__").exists()  # nothing left in the user's folder
    finally:
        effects.REGISTRY.clear()
        effects.REGISTRY.update(registry)


def test_an_effect_file_python_cannot_import_is_refused_in_one_line(tmp_path):
    from calibration.effects import EffectError, load_effect_file

    f = tmp_path / "sintwo.txt"
    f.write_text(EFFECT)
    with pytest.raises(EffectError, match=r"sintwo\.txt: not a Python file"):
        load_effect_file(f)


def test_zero_offsets_shift_the_joint_angles_and_are_recorded(fitted, tmp_path):
    from calibration.exports.params_io import with_zero_offsets, write_zero_update

    p, out = tmp_path / "p.json", tmp_path / "rezeroed.json"
    save_params(fitted, p)
    doc = json.loads(p.read_text())
    doc["unknown_key"] = {"kept": True}
    p.write_text(json.dumps(doc))
    offsets = np.radians([0.0, 0.1, -0.2, 0.0, 0.3, 0.0])
    write_zero_update(p, out, offsets)
    new = json.loads(out.read_text())
    before = {r["name"]: r["value"] for r in doc["parameters"]}
    after = {r["name"]: r["value"] for r in new["parameters"]}
    for j, deg in enumerate([0.0, 0.1, -0.2, 0.0, 0.3, 0.0]):
        name = f"geometric.j{j + 1}.theta"
        assert after[name] == pytest.approx(before[name] + deg)
    assert {k: v for k, v in after.items() if ".theta" not in k} == {
        k: v for k, v in before.items() if ".theta" not in k}
    assert new["history"][-1]["zero_point"]["offsets_deg"] == pytest.approx(
        [0.0, 0.1, -0.2, 0.0, 0.3, 0.0])
    assert new["unknown_key"] == {"kept": True} and "history" not in doc
    load_params(out)  # still a valid params file
    no_geometric = {**doc, "parameters": [r for r in doc["parameters"]
                                          if not r["name"].startswith("geometric.")]}
    with pytest.raises(ParamsError, match=r"no parameter geometric.j1.theta .*model YAML"):
        with_zero_offsets(no_geometric, offsets, "p.json")
