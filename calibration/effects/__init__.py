"""Effects: the physical causes of error a model can include (docs/formats.md §3).

``parse_effects("geometric,base,tool,compliance:2", model)`` builds effect
objects from their names. Families register in :data:`REGISTRY`; a user's file
adds its own with :func:`load_effect_file`.

Modules
-------
base       the Effect interface and its stages, JointEffect, EffectError, display units
geometric  geometric (the DH/MDH table), base (robot in the tracker frame), tool (SMR;
           one point per SMR nest, NestedTool)
tool_frame tool_rotation, the orientation of a 6-DoF target in the flange frame
physical   compliance, harmonic, scale, backlash, coupling, thermal, tracker_scale
table      table:J, a smooth correction table for joint errors no formula captures
drift      thermal_growth, thermal_zero:J (joint temperatures), time_growthK, base_driftK (time)
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import re
import sys
from pathlib import Path
from typing import Any

from ..files import check_regular_file
from ..model.robot_model import RobotModel
from .base import Effect, EffectError, JointEffect, display_unit
from .drift import DRIFT
from .geometric import BUILTIN, Base, Geometric, NestedTool, Tool
from .physical import PHYSICAL
from .table import Table
from .tool_frame import TOOL_FRAME, ToolRotation

REGISTRY: dict[str, type[Effect]] = {**BUILTIN, **TOOL_FRAME, **PHYSICAL, "table": Table,
                                     **DRIFT}

DEFAULT_EFFECTS = "geometric,base,tool"

_NAME = re.compile(r"^(?P<family>[a-z][a-z_]*?)(?P<order>\d*)(?::(?P<joint>\d+))?"
                   r"(?:@(?P<range>[^@]*))?$")
#: the range of an effect that takes one (``table2:2@-186..-126``): LO..HI, degrees
_RANGE = re.compile(r"^(?P<lo>[-+]?\d+(?:\.\d+)?)\.\.(?P<hi>[-+]?\d+(?:\.\d+)?)$")

__all__ = [
    "DEFAULT_EFFECTS",
    "REGISTRY",
    "Base",
    "Effect",
    "EffectError",
    "Geometric",
    "JointEffect",
    "NestedTool",
    "Tool",
    "ToolRotation",
    "display_unit",
    "effect_source",
    "load_effect_file",
    "parse_effect",
    "parse_effects",
    "register",
]


#: the families cellcal ships: a user effect replaces one only when it says so
BUILTIN_FAMILIES = frozenset(REGISTRY)


def register(cls: type[Effect]) -> type[Effect]:
    """Make a family available by name (usable as a class decorator).

    A class may not take over a built-in family's name unless it declares
    ``replaces_builtin = True`` (a user's file must not silently change what
    ``geometric`` means)."""
    if not cls.family or not re.fullmatch(r"[a-z][a-z_]*", cls.family):
        raise EffectError(f"{cls.__name__}: family {cls.family!r} must be lower-case "
                          "letters/underscores")
    if cls.stage not in ("joint", "table", "length", "tool", "target", "base", "drift",
                         "measure"):
        raise EffectError(f"{cls.__name__}: unknown stage {cls.stage!r}")
    current = REGISTRY.get(cls.family)
    if (cls.family in BUILTIN_FAMILIES and current is not cls
            and current.__module__.startswith(__name__)
            and not getattr(cls, "replaces_builtin", False)):
        raise EffectError(f"{cls.__name__}: family {cls.family!r} is a built-in effect; a user "
                          "effect replaces it only if it says so (class attribute "
                          "replaces_builtin = True)")
    REGISTRY[cls.family] = cls
    return cls


def effect_source(cls: type[Effect]) -> tuple[str, str] | None:
    """(file name, sha256) of the user file that defined ``cls``; None for a built-in."""
    return getattr(cls, "_cellcal_source", None)


def parse_effect(name: str, model: RobotModel) -> Effect:
    """One effect from its command-line name (``compliance:3``, ``harmonic12:1``, a table
    with its knots' range ``table2:2@-186..-126``)."""
    m = _NAME.match(name.strip())
    if not m:
        raise EffectError(f"bad effect name {name!r}: expected family or family:J")
    family, order, joint = m["family"], m["order"], m["joint"]
    cls = REGISTRY.get(family) or REGISTRY.get(family + order)
    if cls is None:
        raise EffectError(
            f"unknown effect family {family!r} in {name!r}; known: {', '.join(sorted(REGISTRY))}"
        )
    if cls.family == family + order:  # a family whose name ends in digits
        order = ""
    args = (model, int(joint) if joint else None, int(order) if order else None)
    if m["range"] is None:
        return cls(*args)
    if not getattr(cls, "takes_range", False):
        raise EffectError(f"effect {cls.family!r} takes no range ('@...' in {name!r})")
    r = _RANGE.match(m["range"])
    if not r or not float(r["lo"]) < float(r["hi"]):
        raise EffectError(f"bad range in {name!r}: expected @LO..HI in degrees, LO < HI "
                          "(e.g. table2:2@-186..-126)")
    # a family that takes a range (a table) takes these keywords
    ranged: Any = cls
    return ranged(*args, range_deg=(float(r["lo"]), float(r["hi"])), explicit_range=True)


def parse_effects(spec: str | list[str], model: RobotModel) -> list[Effect]:
    """Effects from a comma-separated list or a list of names; duplicates refused."""
    names = [s.strip() for s in spec.split(",")] if isinstance(spec, str) else list(spec)
    names = [n for n in names if n]
    if not names:
        raise EffectError("no effects given")
    effects = [parse_effect(n, model) for n in names]
    labels = [e.label for e in effects]
    dupes = sorted({x for x in labels if labels.count(x) > 1})
    if dupes:
        raise EffectError(f"effect(s) given twice: {', '.join(dupes)}")
    stages = [e.stage for e in effects]
    for stage in ("base", "tool", "target", "table", "measure", "length", "drift"):
        if stages.count(stage) > 1:
            raise EffectError(f"only one effect may act at the {stage!r} stage")
    return effects


def load_effect_file(path: str | Path) -> list[type[Effect]]:
    """Import a user's Python file and register every Effect subclass it defines.

    This runs the file's code: call it only for a file the user named (``--effect-file``),
    never for a path read from a data file. Each class remembers the file's name and
    sha256 (:func:`effect_source`), so params.json can record them and check them on
    reading."""
    path = check_regular_file(path, EffectError, "effect file")
    source = path.read_bytes()
    digest = hashlib.sha256(source).hexdigest()
    mod_name = f"cellcal_user_effect_{path.stem}"
    spec = importlib.util.spec_from_file_location(mod_name, path)
    if spec is None or spec.loader is None:  # a name Python does not import (no .py)
        raise EffectError(f"{path}: not a Python file (.py)")
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    no_bytecode = sys.dont_write_bytecode
    sys.dont_write_bytecode = True  # no __pycache__ left in the user's folder
    try:
        spec.loader.exec_module(module)
    except Exception as e:  # a user's file: report whatever it raised
        sys.modules.pop(mod_name, None)
        detail = " ".join(str(e).split())
        raise EffectError(f"{path}: could not load: {type(e).__name__}: {detail}") from None
    finally:
        sys.dont_write_bytecode = no_bytecode
    found = [
        obj
        for obj in vars(module).values()
        if inspect.isclass(obj)
        and issubclass(obj, Effect)
        and obj.__module__ == mod_name
        and obj.family
    ]
    if not found:
        raise EffectError(f"{path}: defines no Effect subclass with a family name")
    for cls in found:
        try:
            register(cls)
        except EffectError as e:
            raise EffectError(f"{path}: {e}") from None
        cls._cellcal_source = (path.name, digest)
    return found
