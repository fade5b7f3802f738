"""Capture routines: each turns its parameters and a robot model into a :class:`~daq.plans.Plan`.

Modules
    ``_common``   start postures, nominal points, expected joints of Cartesian targets
    ``frame``     measurement-frame setup: the joint-1 circle and the x line; fits the frame
    ``steps``     axis-wise step moves along x, y, z (absolute positioning error)
    ``zero20``    20 postures on 4 planes through one point, with its closed-loop acquisition
    ``poses``     random or observability-optimised calibration/validation poses
    ``iso9283``   pose accuracy and repeatability cycles (ISO 9283 cube points)
    ``warmup``    work the robot until a reference pose stops drifting (before a capture)
    ``validate``  a program's waypoints, as written and compensated (``cellcal validate``)

Every routine module provides

``make_plan(model, **params) -> Plan``
    The plan (plain data, checked by :func:`daq.check.check_plan` before motion).

and optionally

``resolve_params(params, open_store) -> dict``
    Parameters that refer to earlier runs, resolved against the run store
    (``open_store()`` opens it): zero20's ``--replay RUN``.
``enough(plan, samples, run) -> str | None``
    Checked after every stored point: a reason ends the run there, completed (the
    routine's goal reached: warmup's settled reference).
``finalize(plan, samples, run) -> dict | None``
    What the routine computes once every point is stored (``frame`` and/or
    ``summary`` for the run) from the run's :class:`~daq.store.Samples`, e.g. the
    measurement frame of ``frame``.
``ACQUIRE_OPTIONS``, ``acquisition(model, context) -> Acquisition``
    Adaptive acquisition (:class:`daq.executor.Acquisition`): the options model (stored
    in the run context's ``acquire``) and the strategy the executor calls at each point
    in place of the single read-joints → measure (zero20's closed loop).

A routine's command-line options (``cellcal capture ROUTINE ...``) live with the
command line: :mod:`cellcal.flags.routine_args`.
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
    "warmup": "daq.routines.warmup",
    "validate": "daq.routines.validate",
}


def get(name: str):
    """The module of routine ``name``; ``ValueError`` naming the known ones."""
    if name not in ROUTINES:
        raise ValueError(f"unknown routine {name!r}; known: {', '.join(ROUTINES)}")
    return importlib.import_module(ROUTINES[name])


def make_plan(name: str, model, **params):
    """Plan of routine ``name`` for ``model``."""
    return get(name).make_plan(model, **params)
