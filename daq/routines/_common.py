"""Helpers shared by the routines: start postures, nominal points, expected joints of
Cartesian targets."""

from __future__ import annotations

import numpy as np

from calibration.model.inverse import ChainFK, solve_ik


def default_start(model) -> np.ndarray:
    """A start posture (rad): the middle of each joint's limits, clipped to +-180 deg."""
    lim = np.clip(model.limits_rad(), -np.pi, np.pi)
    return lim.mean(axis=1)


def nominal_point(model, q) -> np.ndarray:
    """Nominal tool point (mm, base frame) at joints q (rad, (N,))."""
    return ChainFK.from_model(model).point(np.asarray(q, float)[None])[0]


def expected_joints(model, xyz: np.ndarray, q_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joints at which the nominal model reaches each Cartesian target, near ``q_start``.

    What a controller's linear move does: position targets keeping the start's
    flange orientation for 6+ joint arms, position only for smaller arms; each
    solved from the previous target's joints (a chain of moves).

    Returns
    -------
    q : (n, N) rad
    ok : (n,) bool, the target was reached (else the dry run names it unreachable)
    """
    fk = ChainFK.from_model(model)
    q_prev = np.asarray(q_start, float)
    R = fk(q_prev[None])[1][0] if model.n_joints >= 6 else None
    out, ok = [], []
    for p in np.atleast_2d(np.asarray(xyz, float)):
        r = solve_ik(fk, q_prev, p, R, limits=model.limits_rad(), success_mm=1e-3,
                     success_rad=1e-6)
        out.append(r.q[0])
        ok.append(bool(r.success[0]))
        if r.success[0]:
            q_prev = r.q[0]
    return np.array(out), np.array(ok)


# ------------------------------------------------------------ visibility
def knows_tracker(cell) -> bool:
    """Whether a plan can be made for the tracker's line of sight (a cell with a tracker)."""
    return cell is not None and cell.tracker is not None


def visibility_params(cell) -> dict | None:
    """What a plan records about the cell it was made for (None: visibility not checked)."""
    if not knows_tracker(cell):
        return None
    return {"tracker_mm": [round(float(v), 3) for v in cell.tracker_mm],
            "tracker_source": cell.tracker_source, "smr_axis": list(cell.smr.axis),
            "reflector": cell.smr.reflector, "half_angle_deg": cell.smr.half_angle_deg,
            "facing_margin_deg": cell.margins.facing_deg,
            "clearance_mm": cell.margins.clearance_mm,
            "fixtures": [f.name for f in cell.fixtures]}


def hidden(model, q: np.ndarray, cell) -> list[tuple[int, str]]:
    """(row, reason) of every joint vector of ``q`` (n, N) the tracker would not see."""
    from calibration.cell.visibility import assess

    if not knows_tracker(cell) or len(q) == 0:
        return []
    s = assess(model, q, cell)
    return [(int(i), s.reason(int(i))) for i in np.flatnonzero(~s.visible)]


def require_visible(routine: str, model, q: np.ndarray, labels, cell, change: str) -> None:
    """Refuse (:class:`~daq.errors.NotEnoughVisible`, exit 3) when the tracker would not see
    some of the joint vectors ``q`` (n, N); the message lists them and says what to change."""
    from ..errors import NotEnoughVisible

    bad = hidden(model, q, cell)
    if not bad:
        return
    lines = [f"{routine}: the tracker at {np.round(cell.tracker_mm).tolist()} mm "
             f"({cell.tracker_source}) would not see {len(bad)} of {len(q)} points:"]
    lines += [f"  point {i} ({labels[i]}): {why}" for i, why in bad[:20]]
    if len(bad) > 20:
        lines.append(f"  ... and {len(bad) - 20} more")
    lines.append(f"change: {change}")
    raise NotEnoughVisible("\n".join(lines))


def what_hides(model, cell, *, floor_z_mm: float | None = 0.0,
               max_reach_mm: float | None = None) -> str:
    """Why the tracker sees no pose at all, as advice naming the flag that fixes it: the SMR
    inside the wrist (the tool offset), else the one constraint that hides the most of the
    poses drawn facing it (:mod:`calibration.cell.sight_cause`); "" when nothing stands out."""
    from calibration.cell.sight_cause import smr_inside_link
    from calibration.cell.sight_cause import what_hides as hiding

    inside = smr_inside_link(model, cell.margins.clearance_mm)
    if inside is not None:
        link, radius = inside
        tool = np.linalg.norm(model.tool_mm())
        return (f"the SMR is inside the wrist: the tool offset puts it {tool:.0f} mm from the "
                f"flange centre, within link {link} ({radius:g} mm radius + "
                f"{cell.margins.clearance_mm:g} mm clearance), so the wrist is in every beam; "
                "give the SMR's position on the flange with --tool-mm X,Y,Z (e.g. 0,0,60 for "
                "a 60 mm holder)")
    h = hiding(model, cell, np.random.default_rng(0), floor_z_mm=floor_z_mm,
               max_reach_mm=max_reach_mm)
    if h.n == 0:
        return ("no pose is within the workspace: a lower --floor-z-mm or no --max-reach-mm")
    if h.hidden == 0:
        return ""
    share = f"{h.hidden} of {h.n} poses drawn facing the tracker"
    if h.what == "facing":
        return (f"the SMR faces away from the tracker at {share}: check the SMR axis and "
                "reflector in the cell file (smr.axis, smr.reflector)")
    if h.what.startswith("fixture"):
        return (f"{h.what} is in the beam at {share}: move the tracker, or check the "
                "fixture in the cell file")
    return (f"{h.what} is in the beam at {share}: move the tracker (--tracker-at) where "
            "the arm does not stand between it and the SMR")


def facing_starts(model, cell, *, radii=(700.0, 900.0, 1100.0), heights=(250.0, 550.0, 850.0),
                  azimuths_deg=tuple(range(-120, 121, 15)), seed: int = 0,
                  min_sv: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Candidate start postures whose SMR faces the tracker straight on: SMR positions at
    ``radii`` from the base axis, ``heights`` above the base, at ``azimuths_deg`` from the
    tracker's azimuth, solved by pose IK from a few fixed starts; only those the tracker
    sees with the cell's margins, above the floor, away from singularities (smallest
    singular value of the Jacobian [Jp / 1 m; Jw] at least ``min_sv``). Returns
    (q (m, N) rad, clearance (m,) mm: how far the beam passes the nearest link)."""
    from calibration.cell.visibility import assess, solve_facing, workspace_ok

    T = cell.tracker_mm
    az0 = np.arctan2(T[1], T[0])
    R, H, A = np.meshgrid(radii, heights, az0 + np.radians(azimuths_deg), indexing="ij")
    p = np.stack([R.ravel() * np.cos(A.ravel()), R.ravel() * np.sin(A.ravel()), H.ravel()], 1)
    lim = np.clip(model.limits_rad(), -np.pi, np.pi)
    seeds = np.random.default_rng(seed).uniform(lim[:, 0], lim[:, 1], (4, model.n_joints))
    seeds = np.vstack([default_start(model), seeds])
    P = np.repeat(p, len(seeds), axis=0)
    q, ok = solve_facing(model, P, T - P, np.zeros(len(P)), np.tile(seeds, (len(p), 1)),
                         cell.smr.axis_unit())
    q = q[ok]
    if model.n_joints < 6 or len(q) == 0:
        return np.zeros((0, model.n_joints)), np.zeros(0)
    q = q[workspace_ok(model, q) & np.all(np.abs(q) <= np.pi + 1e-9, axis=1)]
    # away from singularities: the smallest singular value of [Jp / 1 m; Jw]
    _, _, Jp, Jw = ChainFK.from_model(model)(q)
    sv = np.linalg.svd(np.concatenate([Jp / 1000.0, Jw], axis=1), compute_uv=False)
    q = q[sv[:, -1] >= min_sv] if len(q) else q
    if len(q) == 0:
        return q, np.zeros(0)
    s = assess(model, q, cell)
    return q[s.visible], s.clearance_mm[s.visible].min(axis=1, initial=np.inf)


def facing_start(model, cell, routine: str, change: str, points) -> np.ndarray:
    """The start posture (rad) for a routine that moves from it: the first of the postures
    whose SMR faces the tracker straight on (:func:`facing_starts`) from which every point
    of the routine is reachable and visible. Tried in order of room to move: whose beam
    passes the links by twice the margin first, then the SMR nearest 55 % of the arm's
    reach from the base axis and 500 mm up. ``points(q0)`` gives the routine's expected
    joints (n, N), whether each is reached (n,) and labels. Refused
    (:class:`~daq.errors.NotEnoughVisible`) with the best start's problems when none fits.
    """
    from calibration.cell.visibility import smr_pose

    from ..errors import NotEnoughVisible

    q, clear = facing_starts(model, cell)
    if len(q) == 0:
        cause = what_hides(model, cell)
        raise NotEnoughVisible(f"{routine}: no start posture found whose SMR faces the tracker "
                               f"at {np.round(cell.tracker_mm).tolist()} mm "
                               f"({cell.tracker_source}); "
                               f"{f'the cause: {cause}; ' if cause else ''}change: {change}")
    p, _ = smr_pose(model, q, cell.smr.axis_unit())
    reach = float(np.sum(np.abs(model.dh_table()[:, 1:3])))
    miss = np.abs(np.hypot(p[:, 0], p[:, 1]) - 0.55 * reach) + np.abs(p[:, 2] - 500.0)
    miss = np.where(clear >= 2 * cell.margins.clearance_mm, miss, miss + 1e6)
    best = None
    for k in np.argsort(miss, kind="stable")[:40]:
        qs, ok, labels = points(q[k])
        bad = len(hidden(model, qs, cell)) + int((~ok).sum())
        if bad == 0:
            return q[k]
        if best is None or bad < best[0]:
            best = bad, k, qs, labels, ok
    _, k, qs, labels, ok = best
    if not ok.all():
        raise NotEnoughVisible(f"{routine}: from every start posture facing the tracker some "
                               f"points are out of reach (best: "
                               f"{', '.join(np.asarray(labels)[~ok][:10])}); change: {change}")
    require_visible(routine, model, qs, labels, cell, change)
    return q[k]
