"""Issue 34: the calibrated envelope, the tables' knot support, one model from diagnosis to
robot (parity for every effect family), and a diagnosis that checks extrapolation."""

import json
from dataclasses import replace

import numpy as np
import pytest

from calibration import Dataset, ErrorModel, identify, load_model
from calibration.diagnosis.auto_diagnosis import auto_diagnose, heldout_errors
from calibration.diagnosis.screening import blocked_errors, range_blocks
from calibration.effects import BUILTIN_FAMILIES, EffectError, parse_effect, parse_effects
from calibration.effects.table import MIN_KNOT_POSES, Table
from calibration.errors import OutsideEnvelope, ParamsError
from calibration.exports.params_io import fit_to_dict, params_from_doc
from calibration.fit.envelope import (
    Envelope,
    identify_supported,
    outside_envelope,
    refuse_outside,
    split_stats,
    supported_model,
    values_by_name,
)
from calibration.fit.simulate import (
    Bump,
    random_joints,
    realistic_truth,
    simulate,
    warmup_temperatures,
)

UR = load_model("ur10e")
SIGMA = 0.015


def _joints(rng, n, lo, hi, joint=2):
    q = random_joints(UR, n, rng)
    q[:, joint - 1] = np.radians(rng.uniform(lo, hi, n))
    return q


# ---- the envelope ---------------------------------------------------------------------------
def test_envelope_of_the_calibration_rows_round_trips_and_names_what_lies_beyond():
    rng = np.random.default_rng(0)
    q = _joints(rng, 50, -150, -90)
    t = np.arange(50) * 60.0
    data = Dataset(q=q, tracker_p_smr=np.zeros((50, 3)), t_s=t, temp_c=np.full(50, 21.0),
                   joint_temp=warmup_temperatures(t, 6))
    em = ErrorModel(UR, "geometric,base,tool,base_drift,thermal_zero:2")
    env = Envelope.of_data(data, em)
    assert env.n_poses == 50 and env.t_s == (0.0, 49 * 60.0)
    assert env.joints_deg[1] == pytest.approx((np.degrees(q[:, 1]).min(),
                                               np.degrees(q[:, 1]).max()))
    assert env.temp_c is None  # no effect reads the air temperature
    assert env.joint_temp_c is not None
    doc = json.loads(json.dumps(env.to_json()))
    assert Envelope.from_json(doc, 6, "p.json") == env
    assert Envelope.from_json(None, 6, "p.json") is None  # a file from before: no check
    # inside: the data themselves (and their edges, to a rounding); beyond: named
    assert not any(env.outside_names(q, {"t_s": t}))
    edge = q[[int(np.argmax(q[:, 1]))]].copy()
    edge[0, 1] += np.radians(1e-9)
    assert env.outside_names(edge) == [[]]
    far = q[:3].copy()
    far[0, 1], far[1, 4] = np.radians(-80.0), np.radians(400.0)
    names = env.outside_names(far, {"t_s": np.array([0.0, 10.0, 1e6]),
                                    "joint_temp": np.full((3, 6), 20.0)})
    assert names[0][0] == "q2" and "q5" in names[1] and "t_s" in names[2]
    assert outside_envelope(None, far) == [[], [], []]
    with pytest.raises(OutsideEnvelope, match=r"t\.csv: 3 of 3 targets.*t1: q2") as e:
        refuse_outside(names, ["t1", "t2", "t3"], "targets", "t.csv")
    assert e.value.exit_code == 3
    refuse_outside([[], []], ["a", "b"], "targets", "t.csv")  # inside: nothing refused
    # split statistics: rows beyond counted per quantity
    valid = Dataset(q=far, tracker_p_smr=np.zeros((3, 3)))
    split = split_stats(env, valid, np.ones((3, 3)))
    assert split["inside"]["n"] == 1 and split["outside"]["n"] == 2
    assert split["outside"]["by_quantity"] == {"q2": 1, "q5": 1}


@pytest.mark.parametrize("rec, message", [
    ("wide", "not an object"),
    ({"version": 9, "joints_deg": []}, "newer"),
    ({"version": 1, "joints_deg": [[0, 1]] * 5}, "6 ranges"),
    ({"version": 1, "joints_deg": [[1, 0]] * 6}, r"joints_deg\.0"),
    ({"version": 1, "joints_deg": [[0, 1]] * 6, "t_s": [0, "x"]}, r"envelope\.t_s"),
    ({"version": 1}, "joints_deg missing"),
])
def test_a_bad_envelope_record_is_refused_naming_the_key(rec, message):
    with pytest.raises(ParamsError, match=message):
        Envelope.from_json(rec, 6, "p.json")


# ---- tables: named ranges, supported knots ------------------------------------------------
def test_a_table_named_with_its_range_has_exactly_those_knots():
    t = parse_effect("table2:2@-186..-126", UR)
    assert t.label == "table2:2@-186..-126" and t.prefix == "table2.j2"
    assert t.knots_deg[0] == -186 and t.knots_deg[-1] == -126 and t.n_params == 31
    assert t.with_parameter_names(t.param_names).label == t.label
    assert parse_effect("table:2", UR).label == "table:2"
    for bad, message in (("table2:2@-185..-126", "multiples of 2"),
                         ("table:2@0..10", "at least 20"), ("table:2@5..1", "LO < HI"),
                         ("compliance:2@0..10", "takes no range")):
        with pytest.raises(EffectError, match=message):
            parse_effect(bad, UR)


def test_a_knot_the_data_barely_reach_is_dropped_and_the_table_holds_its_edge_value():
    rng = np.random.default_rng(3)
    theta = np.radians(np.concatenate([rng.uniform(-150, -90.5, 400),
                                       rng.uniform(-90.5, -89.0, 3)]))  # a handful beyond
    full = Table.covering(UR, 2, theta, 2)
    assert full.knots_deg[-1] == -88  # covering spans every angle
    t = full.supported_knots(theta)
    assert t.knots_deg[0] == -150 and t.knots_deg[-1] == -92
    ok = full.knot_support(theta)
    assert not ok[-1] and not ok[-2] and ok[1:-2].all()
    # beyond the last supported knot the correction is constant: the edge knot's value
    p = rng.normal(size=t.n_params)
    beyond = np.radians([-91.0, -85.0, -40.0])
    assert np.allclose(t.basis(beyond) @ p, p[-1])
    # an end knot needs ten poses, whatever its weight
    few = np.radians(np.linspace(-10, 10, MIN_KNOT_POSES + 2))
    assert Table.supported(UR, 2, few, 10).n_params == 3
    # a table named without a range covers the data it is fitted to
    em, notes = supported_model(ErrorModel(UR, "geometric,base,tool,table2:2"),
                                Dataset(q=np.tile(theta[:, None], 6),
                                        tracker_p_smr=np.zeros((theta.size, 3))))
    assert em.effects[-1].knots_deg[[0, -1]].tolist() == [-150, -92] and notes == []
    named = ErrorModel(UR, "geometric,base,tool,table2:2@-160..-80")
    em2, notes = supported_model(named, Dataset(q=np.tile(theta[:, None], 6),
                                                tracker_p_smr=np.zeros((theta.size, 3))))
    assert em2.effects[-1].label == "table2:2@-150..-92" and "cut to -150..-92" in notes[0]


# ---- one model from diagnosis to robot: parity for every family ---------------------------
#: the families that need more than joints and points, and what they need
_COLUMNS = {"thermal": "temp_c", "thermal_growth": "joint_temp", "thermal_zero": "joint_temp",
            "time_growth": "t_s", "base_drift": "t_s", "backlash": "dirs",
            "tool_rotation": "quat"}
FAMILIES = ["compliance:2", "harmonic3:2", "table5:2", "scale:2", "backlash:2", "coupling:3",
            "thermal", "tracker_scale", "thermal_growth", "thermal_zero:2", "time_growth2",
            "base_drift2", "tool_rotation"]


def test_every_built_in_family_is_in_the_parity_test():
    named = {parse_effect(f, UR).family for f in FAMILIES}
    assert named | {"geometric", "base", "tool"} == set(BUILTIN_FAMILIES)


def _capture(effect: str, seed: int = 5):
    """Calibration rows with joint 2 inside [-150, -90] deg, validation rows beyond it (joint
    2 to -80 deg, later in time and warmer)."""
    em = ErrorModel(UR, "geometric,base,tool," + effect)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    n, m = 300, 80
    q = np.vstack([_joints(rng, n, -150, -90), _joints(rng, m, -90, -80)])
    t = np.arange(n + m) * 20.0
    cols = {"is_valid": np.arange(n + m) >= n, "t_s": t,
            "temp_c": 20.0 + t / t.max() * 3, "joint_temp": warmup_temperatures(t, 6)}
    dirs = np.zeros((n + m, 6), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    cols["dirs"] = dirs
    data = simulate(em, x, q, SIGMA, rng, sigma_deg=0.01 if effect == "tool_rotation" else None,
                    **cols)
    return data


@pytest.mark.parametrize("effect", FAMILIES)
def test_the_effect_names_and_params_json_rebuild_the_fitted_model(effect):
    """calibrate's fit (every table over its supported knots); its effect names rebuilt on
    the same data, and its params.json read back, predict the same, to 1e-9 mm, inside the
    data and beyond them (joint 2 beyond its calibrated range, later, warmer)."""
    data = _capture(effect)
    calib = data.calib()
    fit, _ = identify_supported(ErrorModel(UR, "geometric,base,tool," + effect), data)
    inside, beyond = fit.data, fit.valid_data
    assert Envelope.of_fit(fit).outside(beyond.q)[0].any(axis=1).all()
    want_in, want_out = fit.predict(inside), fit.valid_data.tracker_p_smr - fit.valid_residuals
    # the names, rebuilt over the same calibration rows, with the fitted values
    em, _ = supported_model(ErrorModel(UR, fit.error_model.labels), calib)
    assert em.names == fit.error_model.names
    prepared = em.prepare(data)
    x = values_by_name(fit.error_model, fit.values, em, np.zeros(em.n_params))
    for rows, want in ((prepared.calib(), None), (prepared.valid(), want_out)):
        P = em.evaluate(x, em.bind(rows), False)[0]
        if want is None:
            keep = np.isin(rows.pose_id, inside.pose_id)
            P, want = P[keep], want_in
        assert np.abs(P - want).max() < 1e-9
    # params.json read back: the same model, beyond the data too (its thermal record)
    loaded = params_from_doc(json.loads(json.dumps(fit_to_dict(fit))))
    assert loaded.envelope == Envelope.of_fit(fit)
    lem = loaded.error_model
    for rows, want in ((inside, want_in), (replace(beyond, meta={}), want_out)):
        P = lem.evaluate(loaded.values, lem.bind(lem.prepare(rows)), False)[0]
        assert np.abs(P - want).max() < 1e-9


def test_what_the_automatic_diagnosis_returns_rebuilds_the_model_it_diagnosed():
    """The effect string of ``diagnose --auto`` refitted as ``calibrate`` fits it, and its
    ``--out`` params.json, give the diagnosed model: the same structure (a table's knots),
    the same predictions inside and beyond the data."""
    rng = np.random.default_rng(11)
    em = ErrorModel(UR, parse_effects("geometric,base,tool,compliance:2,harmonic2:1", UR)
                    + [Bump(UR, 2, -125.0, 6.0)])
    x = realistic_truth(em, rng)
    calib = simulate(em, x, _joints(rng, 500, -150, -90), SIGMA, rng)
    beyond = simulate(em, x, _joints(rng, 200, -95, -80), SIGMA, rng)
    result = auto_diagnose(identify(ErrorModel(UR), calib), calib)
    assert any(e.startswith("table") for e in result.effects)
    refit, _ = identify_supported(ErrorModel(UR, ",".join(result.effects)), calib)
    assert refit.error_model.names == result.fit.error_model.names
    for rows in (calib, beyond):
        assert np.abs(refit.predict(rows) - result.fit.predict(rows)).max() < 1e-6
    doc = json.loads(json.dumps(fit_to_dict(result.fit, auto=result)))
    loaded = params_from_doc(doc)
    for rows in (calib, beyond):
        P = loaded.error_model.evaluate(loaded.values, loaded.error_model.bind(rows), False)[0]
        assert np.abs(P - result.fit.predict(rows)).max() < 1e-9


# ---- a diagnosis that checks extrapolation ------------------------------------------------
def test_range_blocked_folds_leave_out_the_ends_of_each_joint_and_tie_the_tables():
    data = _capture("table5:2").calib()
    fit, _ = identify_supported(ErrorModel(UR, "geometric,base,tool,table5:2"), data)
    blocks = dict(range_blocks(fit.data))
    assert set(blocks) == {f"q{j}{s}" for j in range(1, 7) for s in "<>"}
    hi = blocks["q2>"]
    assert 0.09 * fit.data.n <= hi.sum() <= 0.11 * fit.data.n
    sq, labels = blocked_errors(fit)
    assert sq.size == labels.size == sum(b.sum() for b in blocks.values())
    # the tied fold is the refit (same smoothing) over the knots the rest supports
    keep = fit.data.subset(~hi)
    em = ErrorModel(UR, "geometric,base,tool,table5:2")
    em.effects[-1].smoothing = fit.error_model.effects[-1].smoothing
    sub, _ = identify_supported(em, keep, outliers="keep")
    assert sub.error_model.effects[-1].knots_deg[-1] < fit.error_model.effects[-1].knots_deg[-1]
    held = fit.data.subset(hi)
    brute = np.sum((held.tracker_p_smr - sub.predict(held)) ** 2, axis=1)
    mine = sq[np.array([lab.endswith("|q2>") for lab in labels])]
    assert mine == pytest.approx(brute, rel=1e-3, abs=1e-7)
    ho = heldout_errors(fit)
    assert ho.blocked is not None and ho.blocked_rms_mm == pytest.approx(np.sqrt(sq.mean()))


def test_calibrated_on_part_of_a_joints_range_the_model_does_no_harm_beyond_it():
    """Joint 2 calibrated over [-150, -90] deg, validated 0-4 deg beyond (as at a plant,
    where programs are taught after the calibration): the automatic diagnosis still finds
    the hidden effects inside, and its model, refitted from its effect names as calibrate
    does, misses the poses beyond no more than the geometric-only fit does."""
    rng = np.random.default_rng(11)
    hidden = "compliance:2,compliance:3,harmonic2:1,table:2"
    truth = ErrorModel(UR, parse_effects("geometric,base,tool," + hidden, UR)
                       + [Bump(UR, 2, -125.0, 6.0)])
    x = realistic_truth(truth, rng)
    calib = simulate(truth, x, _joints(rng, 500, -150, -90), SIGMA, rng)
    inside = simulate(truth, x, _joints(rng, 300, -150, -90), SIGMA, rng)
    beyond = simulate(truth, x, _joints(rng, 300, -90, -86), SIGMA, rng)
    geo = identify(ErrorModel(UR), calib)
    result = auto_diagnose(geo, calib)
    assert {"compliance:2", "compliance:3", "harmonic2:1"} <= set(result.effects)
    assert any(e.startswith("table") and e.endswith(":2") for e in result.effects)
    refit, _ = identify_supported(ErrorModel(UR, ",".join(result.effects)), calib)

    def rms(fit, rows):
        return float(np.sqrt(np.mean(np.sum((rows.tracker_p_smr - fit.predict(rows)) ** 2,
                                            axis=1))))

    floor = calib.noise_floor_mm()
    assert rms(result.fit, inside) < 1.1 * floor < 0.5 * rms(geo, inside)
    assert rms(refit, beyond) <= rms(geo, beyond)
    assert rms(refit, beyond) < 1.2 * floor
    env = Envelope.of_fit(refit)
    assert env.outside(beyond.q)[0][:, 1].mean() > 0.9  # beyond joint 2's range, named
    step = result.steps[0].to_json()
    assert step["range_blocked_rms_mm"] > 0
