"""Capture routines: each turns its parameters and a robot model into a :class:`~daq.plans.Plan`.

Every routine module provides

``make_plan(model, **params) -> Plan``
    The plan (plain data, checked by :func:`daq.check.check_plan` before motion).
``add_args(parser)`` / ``params_from_args(args) -> dict``
    Its command-line options (``cellcal capture ROUTINE ...``).
``finalize(plan, samples, run) -> dict | None``
    Optional: what the routine computes once every point is stored (``frame``
    and/or ``summary`` for the run), e.g. the measurement frame of ``frame``.

Routines: ``frame`` (measurement-frame setup), ``steps`` (axis-wise step
moves), ``zero20`` (20 postures on 4 planes through one target point),
``poses`` (random or observability-optimised calibration/validation poses),
``iso9283`` (pose accuracy and repeatability cycles).
"""

from __future__ import annotations

import importlib

#: routine name -> module
ROUTINES = {
    "frame": "daq.routines.frame",
    "steps": "daq.routines.steps",
    "zero20": "daq.routines.zero20",
    "poses": "daq.routines.poses",
    "iso9283": "daq.routines.iso9283",
}


def get(name: str):
    """The module of routine ``name``; ``ValueError`` naming the known ones."""
    if name not in ROUTINES:
        raise ValueError(f"unknown routine {name!r}; known: {', '.join(ROUTINES)}")
    return importlib.import_module(ROUTINES[name])


def make_plan(name: str, model, **params):
    """Plan of routine ``name`` for ``model``."""
    return get(name).make_plan(model, **params)
