"""``cellcal models``: list the built-in robot models."""

from __future__ import annotations

from calibration import builtin_models, load_model

from .common import print_json, table


def register(sub) -> None:
    p = sub.add_parser("models", help="list the built-in robot models")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    rows = []
    for name in builtin_models():
        m = load_model(name)
        reach = sum(abs(j.a) + abs(j.d) for j in m.joints)
        rows.append({"name": name, "convention": m.convention, "joints": m.n_joints,
                     "mass_model": m.links is not None, "reach_mm": round(reach, 1)})
    if args.json:
        print_json(rows)
        return 0
    print(table([[r["name"], r["convention"], r["joints"], "yes" if r["mass_model"] else "no",
                  f"{r['reach_mm']:.0f}"] for r in rows],
                ["model", "convention", "joints", "mass model", "sum |a|+|d| mm"]))
    return 0
