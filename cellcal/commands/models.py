"""``cellcal models``: list the built-in robot models."""

from __future__ import annotations

from .common import print_json
from .parsers import command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "models", help="list the built-in robot models",
        description="List the built-in robot models: name, DH convention, joints, whether "
        "a mass model (for compliance) is included, and the sum of |a| + |d| (a reach "
        "scale). A model YAML file (docs/formats.md §2) works wherever a name does.")
    p.add_argument("--json", action="store_true", help="print a JSON list")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.models_text import models_table

    from ..usecases.models import builtin_model_summaries

    models = builtin_model_summaries()
    if args.json:
        print_json([m.to_json() for m in models])
    else:
        print(models_table(models))
    return 0
