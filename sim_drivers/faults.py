"""Fault injection for the simulated servers: a small spec language, by probability or schedule.

Spec syntax (comma separated entries, whitespace ignored)::

    beam=0.05,slow=0.02,drop=0.02,garbage=0.02,pstop=0.01,modbus=0.02   # probabilities
    blunder=0.03                                                       # 3 % bad readings
    drop@3,beam@5                                                      # the 3rd / 5th command
    slow=0.1,delay=2.5                                                 # parameter: slow delay, s

``NAME=P`` fires fault ``NAME`` on each command with probability ``P`` (0..1);
``NAME@N`` fires it on the N-th command the server receives (1-based, counted
over all connections of that server); ``delay=S`` sets how long a ``slow``
reply is held back (seconds of wall time, default 2.0). An empty spec means no
faults.

Fault names and what the servers do with them:

========  =================================================================
beam      tracker: the beam breaks during ``MEAS`` (``EVT BEAM_LOST``,
          ``ERR 14 BEAM_BROKEN``, ``EVT BEAM_RESTORED``)
slow      any line server: the reply is held back ``delay`` seconds (longer
          than a client timeout); Modbus server: the response likewise
drop      TCP servers: the server closes the connection instead of replying
          (ignored on a pty; the Modbus server drops the connection too)
garbage   line servers: a line of random non-protocol bytes instead of the reply
pstop     robot servers (and FakeRTDEControl, the in-process robot): a move command
          triggers a protective stop
modbus    Modbus server: the request gets exception response 4
          (SERVER_DEVICE_FAILURE)
stale     Modbus server: the heartbeat register stops counting for that read
blunder   tracker (the cell's injector, so over the wire and in process): the
          reading is displaced by 0.5-5 mm along the line of sight or in a
          random direction (:func:`calibration.fit.simulate.blunder_offsets`), with
          nothing on the wire to tell; the cell records the truth
          (:attr:`sim_drivers.cell.SimCell.blunder_log`)
========  =================================================================

Servers call :meth:`FaultInjector.begin_command` once per command and then
:meth:`FaultInjector.fires` for each fault that applies to that command. Tests
may also :meth:`FaultInjector.arm` a fault for the next applicable command(s).
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger(__name__)

#: every fault name the spec language knows
FAULT_NAMES = ("beam", "slow", "drop", "garbage", "pstop", "modbus", "stale", "blunder")


@dataclass
class FaultSpec:
    """A parsed fault spec: probabilities, schedules and the slow delay."""

    probability: dict[str, float] = field(default_factory=dict)
    schedule: dict[str, set[int]] = field(default_factory=dict)
    delay_s: float = 2.0

    @classmethod
    def parse(cls, text: str | None) -> FaultSpec:
        """Parse ``"beam=0.05,drop@3,delay=1.5"``; raise ``ValueError`` naming the bad entry."""
        spec = cls()
        if not text or not text.strip():
            return spec
        for raw in text.split(","):
            entry = raw.strip()
            if not entry:
                continue
            if "@" in entry:
                name, _, idx = entry.partition("@")
                name = name.strip()
                cls._check_name(name, entry, text)
                try:
                    n = int(idx)
                except ValueError:
                    raise ValueError(
                        f"fault spec {text!r}: entry {entry!r}: command number must be an integer"
                    ) from None
                if n < 1:
                    raise ValueError(f"fault spec {text!r}: entry {entry!r}: command number < 1")
                spec.schedule.setdefault(name, set()).add(n)
            elif "=" in entry:
                name, _, val = entry.partition("=")
                name = name.strip()
                try:
                    x = float(val)
                except ValueError:
                    raise ValueError(
                        f"fault spec {text!r}: entry {entry!r}: value must be a number"
                    ) from None
                if name == "delay":
                    if not x > 0:
                        raise ValueError(f"fault spec {text!r}: entry {entry!r}: delay must be > 0")
                    spec.delay_s = x
                    continue
                cls._check_name(name, entry, text)
                if not 0.0 <= x <= 1.0:
                    raise ValueError(
                        f"fault spec {text!r}: entry {entry!r}: probability must be in [0, 1]"
                    )
                spec.probability[name] = x
            else:
                raise ValueError(
                    f"fault spec {text!r}: entry {entry!r}: expected NAME=P, NAME@N or delay=S"
                )
        return spec

    @staticmethod
    def _check_name(name: str, entry: str, text: str) -> None:
        if name not in FAULT_NAMES:
            raise ValueError(
                f"fault spec {text!r}: entry {entry!r}: unknown fault {name!r}, "
                f"expected one of {', '.join(FAULT_NAMES)}"
            )


class FaultInjector:
    """Decides, command by command, which faults fire. Thread-safe and seeded.

    Parameters
    ----------
    spec : FaultSpec or str or None
        The faults; a string is parsed with :meth:`FaultSpec.parse`.
    seed : int
        Seed of the injector's own random generator (reproducible runs).
    """

    def __init__(self, spec: FaultSpec | str | None = None, *, seed: int = 0) -> None:
        self.spec = spec if isinstance(spec, FaultSpec) else FaultSpec.parse(spec)
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self._armed: dict[str, float] = {}
        self.command_index = 0
        #: (command index, fault name) of every fault that fired
        self.log: list[tuple[int, str]] = []

    @property
    def delay_s(self) -> float:
        """How long a ``slow`` reply is held back (s)."""
        return self.spec.delay_s

    def arm(self, name: str, times: int | None = 1) -> None:
        """Fire ``name`` on the next ``times`` commands to which it applies.

        ``times=None`` keeps it firing on every such command until :meth:`disarm`
        (a fault that a test needs to last "until the client notices" fires by state,
        never by a count a fast machine can use up).
        """
        FaultSpec._check_name(name, name, name)
        with self._lock:
            if times is None:
                self._armed[name] = float("inf")
            else:
                self._armed[name] = self._armed.get(name, 0) + times

    def disarm(self, name: str | None = None) -> None:
        """Forget armed faults (all of them when ``name`` is None)."""
        with self._lock:
            if name is None:
                self._armed.clear()
            else:
                self._armed.pop(name, None)

    def begin_command(self) -> int:
        """Count one more command; returns its 1-based index."""
        with self._lock:
            self.command_index += 1
            return self.command_index

    def fires(self, name: str) -> bool:
        """Whether fault ``name`` fires on the current command (consumes an armed shot)."""
        with self._lock:
            hit = False
            if self._armed.get(name, 0) > 0:
                self._armed[name] -= 1
                hit = True
            elif self.command_index in self.spec.schedule.get(name, ()):
                hit = True
            else:
                p = self.spec.probability.get(name, 0.0)
                hit = p > 0 and float(self._rng.random()) < p
            if hit:
                self.log.append((self.command_index, name))
                log.info("fault %s fired (command %d)", name, self.command_index)
            return hit
