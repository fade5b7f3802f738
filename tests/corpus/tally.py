"""Run the whole corpus and print a table of outcomes per command.

    python -m tests.corpus.tally [--quick] [--json results.json] [--only SUBSTRING]

``--quick`` leaves out the slow (subprocess) cases. Against another checkout of
cellcal, put it first on PYTHONPATH: the corpus only uses the command line and
public readers. The categories are those of :func:`tests.corpus.cases.judge`.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

from .cases import _restore_permissions, build_cases, classify, judge, run_case
from .workspace import build, copy_workspace

KINDS = ("ok", "traceback", "accepted", "loss", "code", "message")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="leave out the slow cases")
    ap.add_argument("--json", metavar="FILE", help="write every case's result here")
    ap.add_argument("--only", default=None, help="only cases whose id contains this")
    ap.add_argument("-v", "--verbose", action="store_true", help="print every failing case")
    args = ap.parse_args(argv)
    cases = [c for c in build_cases() if not (args.quick and c.slow)
             and (args.only is None or args.only in c.id)]
    tmp = Path(tempfile.mkdtemp(prefix="cellcal-corpus-"))
    results = []
    t0 = time.perf_counter()
    try:
        ws0 = build(tmp / "workspace")
        for i, case in enumerate(cases):
            ws = copy_workspace(ws0, tmp / f"case{i}")
            try:
                outcome, before = run_case(case, ws)
                problems = judge(case, outcome, before, ws)
            except Exception as e:  # noqa: BLE001 - the harness itself: count, go on
                outcome, problems = None, [f"traceback: harness: {type(e).__name__}: {e}"]
            finally:
                _restore_permissions(ws)
                shutil.rmtree(ws, ignore_errors=True)
            kind = classify(problems)
            results.append({"id": case.id, "command": case.command, "expected": case.rc,
                            "rc": None if outcome is None else outcome.rc, "kind": kind,
                            "problems": problems})
            if args.verbose and problems:
                print(f"{case.id}: {'; '.join(problems)}", file=sys.stderr)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    by_cmd: dict[str, Counter] = defaultdict(Counter)
    for r in results:
        by_cmd[r["command"]][r["kind"]] += 1
    total = Counter(r["kind"] for r in results)
    width = max(len(c) for c in [*by_cmd, "command", "total"])
    print(f"{'command':<{width}}  {'cases':>5}  " + "  ".join(f"{k:>9}" for k in KINDS))
    for cmd in sorted(by_cmd):
        c = by_cmd[cmd]
        print(f"{cmd:<{width}}  {sum(c.values()):>5}  " + "  ".join(f"{c[k]:>9}" for k in KINDS))
    print(f"{'total':<{width}}  {len(results):>5}  " + "  ".join(f"{total[k]:>9}" for k in KINDS))
    print(f"({time.perf_counter() - t0:.0f} s)")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")
    return 0 if total["ok"] == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
