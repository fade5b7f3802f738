"""The run store's per-sample commit: SQLite file vs PostgreSQL server, one writer and eight.

Each writer is a process with its own :class:`daq.store.RunStore` writing samples of its
own run, one transaction per sample (as the executor does). Measured per commit (wall
clock around ``add_sample``): median, 95th percentile and max; throughput is samples per
second of wall time over all writers. Eight writers are eight simulated cells writing at
full speed into one database (a real cell commits a sample every few seconds).

SQLite: WAL, ``synchronous=FULL`` (the default) and NORMAL. PostgreSQL: a throwaway local
server (:mod:`tests.pg_server`, fsync on, ``synchronous_commit`` on = the default; the
NORMAL row turns it off for the session), over loopback TCP; ``--db URL`` uses a server
of yours instead (it must be an empty database or a run store).

    python benchmarks/store.py [--samples 2000] [--writers 8] [--db postgresql://...]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calibration import load_model  # noqa: E402
from daq.routines import make_plan  # noqa: E402
from daq.store import RunStore, Sample  # noqa: E402

TOY = ROOT / "tests" / "daq" / "data" / "toyarm.yaml"


def _sample(i: int) -> Sample:
    return Sample(point_index=i, q=np.full(6, 0.01 * i),
                  tracker_p_smr=np.array([1000.0 + i, 200.0, 300.0]), std_mm=np.full(3, 0.01),
                  n_averaged=500, t_s=time.time(), pose_id=f"p{i}", temp_c=20.0,
                  cmd=np.array([1.0, 2.0, 3.0]), dirs=np.array([1, 0, -1, 1, 0, 1]),
                  target={"index": i, "q": [0.0] * 6})


def _writer(address: str, synchronous: str, n: int, start, out) -> None:
    """One cell: its own run, ``n`` samples, one commit each; puts the commit times."""
    plan = make_plan("poses", load_model(str(TOY)), count=n, seed=0)
    with RunStore(address, synchronous) as st:
        rid = st.create_run(plan)
        samples = [_sample(i) for i in range(n)]
        start.wait()
        times = np.empty(n)
        for i, s in enumerate(samples):
            t0 = time.perf_counter()
            st.add_sample(rid, s)
            times[i] = time.perf_counter() - t0
        assert st.n_samples(rid) == n
    out.put(times)


def bench(label: str, address: str, synchronous: str, writers: int, n: int) -> list:
    RunStore(address, synchronous).close()  # create / upgrade the schema once, first
    ctx = mp.get_context("spawn")
    start, out = ctx.Barrier(writers + 1), ctx.Queue()
    procs = [ctx.Process(target=_writer, args=(address, synchronous, n, start, out))
             for _ in range(writers)]
    for p in procs:
        p.start()
    start.wait()
    t0 = time.perf_counter()
    times = np.concatenate([out.get(timeout=600) for _ in procs])
    wall = time.perf_counter() - t0
    for p in procs:
        p.join(timeout=60)
        assert p.exitcode == 0, f"a writer failed ({p.exitcode})"
    ms = 1000 * times
    sync = ({"FULL": "sync_commit on", "NORMAL": "sync_commit off"}[synchronous]
            if label.startswith("PostgreSQL") else synchronous)
    return [label, sync, writers, times.size, f"{np.median(ms):.2f}",
            f"{np.percentile(ms, 95):.2f}", f"{ms.max():.1f}", f"{times.size / wall:.0f}"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=2000, help="samples of the one writer")
    ap.add_argument("--writers", type=int, default=8)
    ap.add_argument("--db", help="a PostgreSQL URL (default: a throwaway local server)")
    args = ap.parse_args()
    per_writer = max(args.samples // args.writers, 1)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for sync in ("FULL", "NORMAL"):
            rows.append(bench("SQLite file", str(Path(d) / f"one-{sync}.db"), sync, 1,
                              args.samples))
        rows.append(bench("SQLite file", str(Path(d) / "many.db"), "FULL", args.writers,
                          per_writer))

    def pg_rows(url_of):
        out = [bench("PostgreSQL", url_of(f"one_{s.lower()}"), s, 1, args.samples)
               for s in ("FULL", "NORMAL")]
        out.append(bench("PostgreSQL", url_of("many"), "FULL", args.writers, per_writer))
        return out

    if args.db:
        rows += pg_rows(lambda _name: args.db)
        server = f"server {args.db.split('@')[-1]}"
    else:
        from tests.pg_server import PgServer

        with PgServer.start_new() as pg:
            rows += pg_rows(pg.create_database)
            server = f"throwaway local server (fsync on), {pg.bindir}"
    header = ["store", "sync", "writers", "samples", "commit median ms", "p95 ms", "max ms",
              "samples/s"]
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    print(f"one transaction per sample; PostgreSQL: {server}")
    for r in [header, ["-" * w for w in widths], *rows]:
        print("  ".join(str(c).ljust(w) if i == 0 else str(c).rjust(w)
                        for i, (c, w) in enumerate(zip(r, widths, strict=True))))


if __name__ == "__main__":
    main()
