"""``capture --require-warm N``: a capture starts only on a robot that is warm.

Warm means: the robot's latest completed warm-up (``cellcal capture warmup``,
:mod:`daq.routines.warmup`, of the same robot id in the same store) settled (its
reference stopped drifting: one that ran out of time does not count), ended at most N
minutes ago (by the store's clock: when the run was completed) and, where the robot
reports its joint temperatures and the warm-up recorded them, no joint is more than
:data:`COOLED_K` colder now than at the warm-up's last reference reading (it stood
unpowered, or idle long enough to cool). Otherwise :class:`NotWarm` (exit 2) says which
and what to do; nothing is stored, nothing moves.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from drivers.errors import CommandRejected
from drivers.protocols import JointTemperatures

from .errors import RequestError
from .store import RunStore, StoreError

log = logging.getLogger(__name__)

#: a joint this much colder (K) than at the end of the warm-up has cooled
COOLED_K = 1.0


class NotWarm(RequestError):
    """The robot is not warm enough for a capture that requires it (exit code 2)."""


def require_warm(store: RunStore, robot, robot_id: str | None, max_age_min: float, *,
                 timeout: float = 1.0, now: float | None = None) -> None:
    """Refuse (:class:`NotWarm`) unless the robot's last warm-up is recent and its joints
    have not cooled since (module docstring)."""
    who = f"robot {robot_id}" if robot_id else "the robot"
    again = "run `cellcal capture warmup` first"
    try:
        run = store.latest_run("warmup", robot_id=robot_id)
    except StoreError:
        raise NotWarm(f"--require-warm: no completed warm-up of {who} in "
                      f"{store.address}; {again}") from None
    age_min = ((time.time() if now is None else now) - (run.stopped or 0.0)) / 60.0
    if age_min > max_age_min:
        raise NotWarm(f"--require-warm {max_age_min:g}: the last warm-up of {who} (run "
                      f"{run.id}) ended {age_min:.1f} min ago; {again}")
    warm = run.summary.warmup if run.summary is not None else None
    if warm is None or not warm.settled:  # it ran its time, the robot still drifted
        why = "" if warm is None or not warm.reason else f": {warm.reason}"
        raise NotWarm(f"--require-warm: the last warm-up of {who} (run {run.id}) did not "
                      f"settle{why}; {again}")
    if warm.joint_temp_c is None or not isinstance(robot, JointTemperatures):
        log.info("--require-warm: warm-up run %d of %s ended %.1f min ago and settled",
                 run.id, who, age_min)
        return
    try:
        temps = np.asarray(robot.joint_temperatures(timeout=timeout), float)
    except CommandRejected:
        return
    cooled = np.asarray(warm.joint_temp_c, float) - temps
    log.info("--require-warm: warm-up run %d of %s ended %.1f min ago and settled; joints "
             "now %s °C, at its end %s °C", run.id, who, age_min, np.round(temps, 1).tolist(),
             np.round(np.asarray(warm.joint_temp_c, float), 1).tolist())
    if len(cooled) == len(temps) and cooled.max() > COOLED_K:
        j = int(np.argmax(cooled))
        raise NotWarm(f"--require-warm: joint {j + 1} of {who} has cooled by "
                      f"{cooled[j]:.1f} K since its warm-up (run {run.id}: "
                      f"{warm.joint_temp_c[j]:.1f} °C, now {temps[j]:.1f} °C); {again}")
