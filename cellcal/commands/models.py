"""``cellcal models``: list the built-in robot models."""

from __future__ import annotations

from ..cli import command_parser
from .common import print_json, table


def register(sub) -> None:
    p = command_parser(
        sub, "models", help="list the built-in robot models",
        description="List the built-in robot models: name, DH convention, joints, whether "
        "a mass model (for compliance) is included, and the sum of |a| + |d| (a reach "
        "scale). A model YAML file (docs/formats.md §2) works wherever a name does.")
    p.add_argument("--json", action="store_true", help="print a JSON list")
    p.set_defaults(func=run)


def run(args) -> int:
    from calibration import builtin_models, load_model

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
