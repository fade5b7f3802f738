"""The inputs a robot program needs beside its text: the frames a KRL program refers to
by number (``--frames``) and the options of the program filter
(:class:`cellcal.programs.compensate.Options`), checked and named by their flags."""

from __future__ import annotations

import math

import numpy as np
import yaml

from calibration.files import read_text

from ..errors import UsageError
from ..flags.values import parse_floats
from ..programs.compensate import Options

#: the largest frames file read, bytes
MAX_FRAMES_BYTES = 1 << 20


def _frame(value, where: str) -> tuple[float, ...]:
    try:
        v = (parse_floats(value, 6) if isinstance(value, str)
             else [float(x) for x in value])
    except (TypeError, ValueError) as e:
        raise UsageError(f"{where}: {e}") from None
    if len(v) != 6 or not all(math.isfinite(x) for x in v):
        raise UsageError(f"{where}: give 6 finite numbers X, Y, Z (mm), A, B, C (deg)")
    return tuple(v)


def read_frames(path: str | None) -> tuple[dict[int, tuple], dict[int, tuple]]:
    """(tools, bases) of a frames YAML: ``tools:`` and ``bases:`` mappings from the
    number to ``[X, Y, Z, A, B, C]`` (mm, deg); ({}, {}) without a file. UsageError naming
    the file and the entry."""
    if path is None:
        return {}, {}
    text = read_text(path, UsageError, "frames file", MAX_FRAMES_BYTES)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise UsageError(f"--frames {path}: not YAML: {' '.join(str(e).split())}") from None
    if not isinstance(doc, dict) or not set(doc) <= {"tools", "bases"}:
        raise UsageError(f"--frames {path}: expected a mapping with 'tools' and/or 'bases'")
    out = []
    for key in ("tools", "bases"):
        entries = doc.get(key) or {}
        if not isinstance(entries, dict):
            raise UsageError(f"--frames {path}: {key}: expected number: [X, Y, Z, A, B, C]")
        frames = {}
        for k, v in entries.items():
            if isinstance(k, bool) or not isinstance(k, int) or k < 0:
                raise UsageError(f"--frames {path}: {key}: {k!r} is not a frame number")
            frames[k] = _frame(v, f"--frames {path}: {key}[{k}]")
        out.append(frames)
    return out[0], out[1]


def program_options(error_model, *, frames: str | None, start_deg: str | None,
                    temp_c: float | None, payload_kg: float | None,
                    thermal: dict | None = None):
    """The program filter's :class:`~cellcal.programs.compensate.Options` from the flags;
    a calibration with thermal growth needs ``--temp-c``; ``thermal``: the calibration's
    thermal record (params.json), whose warm state a drift effect is compensated at."""
    for flag, v in (("--temp-c", temp_c), ("--payload-kg", payload_kg)):
        if v is not None and not math.isfinite(v):
            raise UsageError(f"{flag}: {v} is not a finite number")
    if payload_kg is not None and payload_kg < 0:
        raise UsageError(f"--payload-kg: {payload_kg:g} is negative")
    if temp_c is None and any(e.family == "thermal" for e in error_model.effects):
        raise UsageError("the calibration has thermal growth: give --temp-c (the robot's "
                         "temperature when the program runs, °C)")
    seed = None
    if start_deg is not None:
        n = error_model.model.n_joints
        try:
            seed = np.radians(parse_floats(start_deg, n))
        except ValueError as e:
            raise UsageError(f"--start: {e} (deg)") from None
        if not np.isfinite(seed).all():
            raise UsageError(f"--start needs {n} finite angles (deg)")
    tools, bases = read_frames(frames)
    return Options(seed=seed, temp_c=temp_c, payload_kg=payload_kg, tools=tools, bases=bases,
                   thermal=thermal)
