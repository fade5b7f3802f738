"""Scaling: each whole command, as a process, at 150, 1 000, 10 000 and 50 000 poses.

For every size, the inputs are made once (in ``--workdir``, kept between calls): a
measurement CSV of a UR10e with hidden compliance of joint 2 and a twice-per-turn error of
joint 3 (``cellcal simulate``), as many compensation targets (base-frame points with their
nominal joints), and a run store holding one run of that many samples and two recorded
calibrations. Each command then runs as a fresh process (``python -m cellcal``, start-up
included) ``--runs`` times: the median wall time, its ratio to the same command at the
smallest size, and the peak memory of the process (its maximum resident set size). Beside
them, the identification's own solve in this process (``Fit.solve_s``, warm, median).

Two more rows: ``diagnose --auto`` on a 500-pose case shaped like real data (fine
correction tables on three joints, periodic errors on two, a per-pose scatter four times
the tracker's sigma that no effect explains: :func:`real_shaped`), and the solve a fresh
``calibrate`` process reports (``solve_s``: cold) against the same solve repeated in this
process (warm).

BLAS runs on one thread (``OPENBLAS_NUM_THREADS=1`` and its kin in every child).

    python benchmarks/scaling.py                              # the table (an hour)
    python benchmarks/scaling.py --sizes 150,1000 --quick     # small sizes, one run
    python benchmarks/scaling.py --only calibrate,cold        # some rows
    PYTHONPATH=DIR python benchmarks/scaling.py --workdir W   # another checkout, same inputs
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import calibration

#: the checkout measured: the one ``calibration`` is imported from (PYTHONPATH)
ROOT = Path(calibration.__file__).resolve().parents[1]
SIZES = (150, 1000, 10_000, 50_000)
#: the effects hidden in the scaling data (besides geometric, base and tool)
HIDDEN = "compliance:2,harmonic2:3"
ROBOT = "bench/1"
#: every row the script can print
ROWS = ("calibrate", "diagnose", "auto", "report", "compensate", "export", "history",
        "solve", "real", "cold")
#: one BLAS thread in every child (as the commands use for problems this size)
ONE_THREAD = {k: "1" for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}


def env() -> dict:
    return {**os.environ, **ONE_THREAD, "PYTHONPATH": str(ROOT)}


def cellcal(*args: str) -> list[str]:
    return [sys.executable, "-m", "cellcal", *args]


#: ``--cpu``: the process's CPU time (user + system) instead of its wall time
CPU = False
#: ``--quick``: one run of everything, the real-shaped loop cut to two steps
QUICK = False


#: runs a command and prints its wall time, CPU time, peak memory (KiB) and exit code: a
#: small process between this one and the command, because a child forked from a large
#: process reports that process's memory as its own peak (Linux counts it until the exec)
LAUNCHER = """
import os, sys, time
argv = sys.argv[1:]
t = time.perf_counter()
pid = os.fork()
if pid == 0:
    fd = os.open(os.devnull, os.O_WRONLY)
    os.dup2(fd, 1)
    os.execvp(argv[0], argv)
_, status, ru = os.wait4(pid, 0)
wall = time.perf_counter() - t
print(wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss, os.waitstatus_to_exitcode(status))
"""


def run_child(argv: list[str], cwd: Path) -> tuple[float, float, int, str]:
    """Run ``argv`` once: (wall s, or with :data:`CPU` user + system s; peak resident
    memory MiB, exit code, stderr's tail)."""
    p = subprocess.run([sys.executable, "-S", "-c", LAUNCHER, *argv], cwd=cwd, env=env(),
                       capture_output=True, text=True)
    wall, cpu, peak_kib, code = p.stdout.split()
    took = float(cpu) if CPU else float(wall)
    return took, int(peak_kib) / 1024.0, int(code), p.stderr[-400:]


def timed_command(argv: list[str], cwd: Path, runs: int, remove: Path | None = None
                  ) -> tuple[float, float, str | None]:
    """Median time (s) and largest peak memory (MiB) of ``runs`` fresh processes
    (``remove``: the output file, deleted before each run), and how the command failed
    (None: it ran; exit 0, or 1 for a fit that did not converge)."""
    walls, peaks = [], []
    for _ in range(runs):
        if remove is not None:
            remove.unlink(missing_ok=True)
        took, peak, code, err = run_child(argv, cwd)
        walls.append(took)
        peaks.append(peak)
        if code not in (0, 1) or "internal error" in err:
            return took, peak, err.strip().splitlines()[-1] if err.strip() else f"exit {code}"
    return statistics.median(walls), max(peaks), None


# ---- inputs --------------------------------------------------------------------------
def inputs(work: Path, n: int) -> dict[str, Path]:
    """The inputs of size ``n`` in ``work`` (made when missing)."""
    d = work / str(n)
    d.mkdir(parents=True, exist_ok=True)
    files = {"poses": d / "poses.csv", "targets": d / "targets.csv", "store": d / "store.db",
             "params": work / "params.json", "dir": d}
    if not files["poses"].exists():
        subprocess.run(cellcal("simulate", "--model", "ur10e", "--poses", str(n), "--valid",
                               "0", "--hidden", HIDDEN, "--seed", "1", "--out",
                               str(files["poses"])),
                       check=True, env=env(), cwd=ROOT, stdout=subprocess.DEVNULL)
    if not files["params"].exists():
        src = work / "params_poses.csv"
        subprocess.run(cellcal("simulate", "--model", "ur10e", "--poses", "1000", "--valid",
                               "0", "--seed", "2", "--out", str(src)),
                       check=True, env=env(), cwd=ROOT, stdout=subprocess.DEVNULL)
        subprocess.run(cellcal("calibrate", "--model", "ur10e", str(src), "--out",
                               str(files["params"])),
                       check=True, env=env(), cwd=ROOT, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
    if not files["targets"].exists():
        write_targets(files["targets"], n)
    if not files["store"].exists():
        write_store(files["store"], files["poses"], n)
    return files


def write_targets(path: Path, n: int) -> None:
    """``n`` targets of the UR10e's tool in its base frame, with their nominal joints."""
    from calibration import load_model
    from calibration.fit.simulate import random_joints
    from calibration.model.kinematics import forward

    m = load_model("ur10e")
    q = random_joints(m, n, np.random.default_rng(n), 170.0)
    p = forward(m, q)[:, -1, :3, 3]
    cols = np.column_stack([p, np.degrees(q)]).tolist()
    head = "pose_id,x,y,z," + ",".join(f"q{j + 1}" for j in range(m.n_joints))
    body = "".join(f"{i + 1}," + ",".join(map(repr, row)) + "\n" for i, row in enumerate(cols))
    path.write_text(head + "\n" + body)


def write_store(path: Path, poses: Path, n: int) -> None:
    """A run store with one run of the ``n`` poses' samples and two calibrations of
    :data:`ROBOT` (``calibrate --db``, of the first 150 poses and of all of them)."""
    from calibration import load_csv, load_model
    from daq.routines import make_plan
    from daq.run_context import RunContext
    from daq.store import RunStore, Sample

    m = load_model("ur10e")
    data = load_csv(poses, m)
    plan = make_plan("poses", m, count=10, seed=0)  # metadata here: the samples are ours
    with RunStore(path, synchronous="NORMAL") as st:
        rid = st.create_run(plan, RunContext(routine="poses", model="ur10e"), robot_id=ROBOT)
        std = np.full(3, 0.015)
        for i in range(n):
            st.add_sample(rid, Sample(point_index=i, q=data.q[i],
                                      tracker_p_smr=data.tracker_p_smr[i], std_mm=std,
                                      n_averaged=100, t_s=1.7e9 + 2.0 * i,
                                      pose_id=data.pose_id[i]))
        st.set_status(rid, "completed")
    first = path.parent / "first.csv"
    first.write_text("".join(poses.read_text().splitlines(keepends=True)[:153]))
    for src in (first, poses):
        subprocess.run(cellcal("calibrate", "--model", "ur10e", str(src), "--db", str(path),
                               "--robot-id", ROBOT),
                       check=True, env=env(), cwd=ROOT, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)


# ---- the real-shaped case ------------------------------------------------------------------
#: real-shaped: the joints' ranges (deg) as a tracker's view leaves them, the joints with
#: a fine table (2 deg knots) and the periodic errors
REAL_RANGES_DEG = ((-90, 90), (-180, 0), (-160, 20), (-180, 0), (-150, 30), (-120, 120))
REAL_TABLE_JOINTS = (2, 3, 5)
REAL_HIDDEN = ("harmonic:1,harmonic2:1,harmonic3:1,harmonic:4,harmonic2:4,harmonic8:4,"
               "compliance:2,compliance:3,backlash:3,scale:2")
#: the per-pose scatter no effect explains, in tracker sigmas (a real arm's repeatability)
REAL_SCATTER = 4.0


def real_shaped(n: int = 500, seed: int = 11, amp: float = 5e-4):
    """A data set shaped like a real capture: ``n`` calibration poses of a UR10e within
    :data:`REAL_RANGES_DEG`; hidden fine tables on :data:`REAL_TABLE_JOINTS` (2 deg knots,
    60 local bumps 1-3 deg wide, ``amp`` rad each), harmonics of orders 1 to 8 on joints 1
    and 4 (twice their typical size), compliance, backlash and scale
    (:data:`REAL_HIDDEN`); the tracker's sigma 0.015 mm, and each pose scattered by four
    times that (what no effect explains). The automatic diagnosis takes all its 12 steps
    on it, tables and harmonics winning most."""
    from calibration import ErrorModel, load_model
    from calibration.effects import parse_effects
    from calibration.effects.table import Table
    from calibration.fit.simulate import realistic_truth, simulate

    m = load_model("ur10e")
    effects = parse_effects("geometric,base,tool," + REAL_HIDDEN, m)
    tables = [Table(m, j, 2, smoothing=0.0) for j in REAL_TABLE_JOINTS]
    em = ErrorModel(m, effects + tables)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    for e, sl in zip(em.effects, em.slices, strict=True):
        if e.family == "table":
            v = np.zeros(len(e.knots))
            for _ in range(60):
                c, w = rng.uniform(-np.pi, np.pi), np.radians(rng.uniform(1.0, 3.0))
                v += rng.normal(0.0, amp) * np.exp(-0.5 * ((e.knots - c) / w) ** 2)
            x[sl] = v
        elif e.family == "harmonic":
            x[sl] *= 2.0
    lo, hi = np.radians(np.array(REAL_RANGES_DEG, float)).T
    q = rng.uniform(lo, hi, size=(n, m.n_joints))
    dirs = np.zeros((n, m.n_joints), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    sigma = 0.015
    data = simulate(em, x, q, sigma, rng, is_valid=np.zeros(n, bool), dirs=dirs)
    data.tracker_p_smr = data.tracker_p_smr + rng.normal(0.0, REAL_SCATTER * sigma, (n, 3))
    return data


# ---- in-process rows ------------------------------------------------------------------------
def solve_ms(poses: Path, runs: int) -> float:
    """Median warm ``Fit.solve_s`` (ms) of the default model on ``poses``, in this process."""
    from threadpoolctl import threadpool_limits

    from calibration import ErrorModel, identify, load_csv, load_model

    m = load_model("ur10e")
    data = load_csv(poses, m)
    with threadpool_limits(limits=1, user_api="blas"):
        identify(ErrorModel(m), data)
        return 1000 * statistics.median(identify(ErrorModel(m), data).solve_s
                                        for _ in range(runs))


def command_solve_ms(poses: Path, runs: int) -> float:
    """Median ``solve_s`` (ms) that ``cellcal calibrate --json`` reports: the first solve
    of a fresh process (cold)."""
    out = []
    for _ in range(runs):
        p = subprocess.run(cellcal("calibrate", "--model", "ur10e", str(poses), "--json"),
                           env=env(), cwd=ROOT, capture_output=True, text=True, check=True)
        out.append(1000 * json.loads(p.stdout)["solve_s"])
    return statistics.median(out)


# ---- the table ------------------------------------------------------------------------------
COMMANDS = {
    "calibrate": lambda f: (cellcal("calibrate", "--model", "ur10e", str(f["poses"])), None),
    "diagnose": lambda f: (cellcal("diagnose", "--model", "ur10e", str(f["poses"])), None),
    "auto": lambda f: (cellcal("diagnose", "--auto", "--model", "ur10e", str(f["poses"])),
                       None),
    "report": lambda f: (cellcal("report", "--model", "ur10e", str(f["poses"]), "--out",
                                 str(f["dir"] / "report.html")), f["dir"] / "report.html"),
    "compensate": lambda f: (cellcal("compensate", "--params", str(f["params"]),
                                     str(f["targets"]), "--out", str(f["dir"] / "comp.csv")),
                             f["dir"] / "comp.csv"),
    "export": lambda f: (cellcal("export", "--db", str(f["store"]), "--out",
                                 str(f["dir"] / "export.csv")), f["dir"] / "export.csv"),
    "history": lambda f: (cellcal("history", "--db", str(f["store"]), ROBOT), None),
}
LABELS = {"calibrate": "calibrate", "diagnose": "diagnose", "auto": "diagnose --auto",
          "report": "report", "compensate": "compensate (n targets)",
          "export": "export (n samples)", "history": "history"}


def main() -> None:
    ap = argparse.ArgumentParser(description="The scaling table of docs/speed.md.")
    ap.add_argument("--sizes", default=",".join(map(str, SIZES)),
                    help="comma-separated pose counts (default %(default)s)")
    ap.add_argument("--runs", type=int, default=3, help="processes per figure (median)")
    ap.add_argument("--quick", action="store_true",
                    help="one run each, the real-shaped loop two steps (that it works)")
    ap.add_argument("--only", default=",".join(ROWS), metavar="ROWS",
                    help=f"comma-separated rows of {', '.join(ROWS)} (default all)")
    ap.add_argument("--workdir", help="keep the inputs here (default: a temporary folder)")
    ap.add_argument("--cpu", action="store_true",
                    help="CPU time (user + system) of each process instead of wall time")
    a = ap.parse_args()
    rows = a.only.split(",")
    if set(rows) - set(ROWS):
        ap.error(f"--only: unknown rows {', '.join(sorted(set(rows) - set(ROWS)))}")
    sizes = [int(s) for s in a.sizes.split(",")]
    global CPU, QUICK
    CPU, QUICK = a.cpu, a.quick
    runs = 1 if a.quick else a.runs
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(a.workdir or tmp)
        table(work, sizes, rows, runs)


def table(work: Path, sizes: list[int], rows: list[str], runs: int) -> None:
    clock = "CPU (user + system)" if CPU else "wall"
    print(f"one BLAS thread; median {clock} time of {runs} fresh process(es) (x: the ratio to "
          f"{sizes[0]} poses), peak resident memory; load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores\n")
    files = {n: inputs(work, n) for n in sizes}
    print(f"| {'poses':<24} |" + "|".join(f" {n:>25} " for n in sizes) + "|")
    print(f"|{'-' * 26}|" + "|".join("-" * 27 for _ in sizes) + "|")
    for name in (r for r in rows if r in COMMANDS):
        cells, first = [], None
        for n in sizes:
            argv, out = COMMANDS[name](files[n])
            wall, peak, failed = timed_command(argv, files[n]["dir"], runs, out)
            if failed:
                print(f"  {LABELS[name]}, {n} poses: failed after {wall:.1f} s, {peak:.0f} "
                      f"MiB: {failed}", file=sys.stderr)
                cells.append(f"fails after {wall:.1f} s")
                continue
            first = first or wall
            cells.append(f"{wall:7.2f} s {wall / first:4.1f}x {peak:5.0f} MiB")
        print(f"| {LABELS[name]:<24} |" + "|".join(f" {c:>25} " for c in cells) + "|",
              flush=True)
    if "solve" in rows:
        cells = [f"{solve_ms(files[n]['poses'], runs):7.1f} ms" for n in sizes]
        print(f"| {'solve, in process':<24} |" + "|".join(f" {c:>25} " for c in cells) + "|")
    if "real" in rows:
        csv = work / "real500.csv"
        if not csv.exists():
            real_shaped(500).to_csv(csv)
        argv = cellcal("diagnose", "--auto", "--model", "ur10e", str(csv),
                       *(["--max-steps", "2"] if runs == 1 and QUICK else []))
        wall, peak, failed = timed_command(argv, work, runs)
        print(f"\ndiagnose --auto, 500 real-shaped poses: {wall:.2f} s, {peak:.0f} MiB"
              + (f" (failed: {failed})" if failed else ""))
        out = subprocess.run(argv + ["--json"], env=env(), cwd=work, capture_output=True,
                             text=True).stdout
        if out.strip():
            doc = json.loads(out)
            print(f"  {len(doc['steps'])} steps: {', '.join(s['effect'] for s in doc['steps'])}"
                  f"; {doc['stop_reason']}")
    if "cold" in rows:  # the identification benchmark's problem: no hidden effect
        n = 1000 if 1000 in sizes else sizes[0]
        clean = work / f"clean{n}.csv"
        if not clean.exists():
            subprocess.run(cellcal("simulate", "--model", "ur10e", "--poses", str(n),
                                   "--valid", "0", "--seed", "1", "--out", str(clean)),
                           check=True, env=env(), cwd=ROOT, stdout=subprocess.DEVNULL)
        cold = command_solve_ms(clean, max(runs, 5))
        warm = solve_ms(clean, max(runs, 5))
        print(f"first solve of a fresh calibrate process, {n} poses: {cold:.1f} ms; warm, "
              f"in process: {warm:.1f} ms ({cold / warm:.2f}x)")
    print(f"\nload average afterwards {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
