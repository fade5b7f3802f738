"""Memory: what a command over n poses will need, what the machine has, and a refusal
before starting when it does not fit.

A command's memory grows linearly with the poses (no n x n array anywhere): per pose, a
fixed part (the chain's frames and their derivatives, the data) and a part per parameter
(the Jacobian and the copies the solver, the covariance and the blunder test make of it).
:data:`WORK` holds those two figures per kind of work, measured as the peak resident
memory of the commands at 10 000 and 20 000 poses (docs/speed.md, "Scaling"), rounded up.

What the machine has (:func:`available_bytes`) is the least of the memory the system
reports available (``MemAvailable`` of /proc/meminfo, else ``os.sysconf``), the room left
in a control group's ``memory.max`` and the address space left under ``RLIMIT_AS`` when
a limit is set. :func:`check_memory` raises :class:`~calibration.errors.TooLarge` (exit 3)
when the work would need more, naming the size that would fit.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from ..errors import TooLarge

#: bytes per pose of each kind of work: (fixed, per parameter), and the share of the
#: parameters' part a pose costs in the work's largest step (see the module docstring)
WORK: dict[str, tuple[float, float]] = {
    # identification with the blunder test, the uncalibrated baseline, the blindness
    "fit": (6_000.0, 160.0),
    # the ranking of every candidate: a fit, the candidates' columns in batches, refits
    "diagnose": (16_000.0, 320.0),
    # the automatic loop: the ranking's and the refits' arrays of a fit with many tables
    "auto": (24_000.0, 400.0),
    # compensation of targets: the inverse kinematics' chain and Jacobian per target
    "compensate": (8_000.0, 0.0),
}
#: what the estimate keeps in reserve besides (interpreter, libraries, the data read)
RESERVE_BYTES = 64 << 20


def need_bytes(work: str, n_poses: int, n_params: int) -> int:
    """Bytes the ``work`` over ``n_poses`` with ``n_params`` parameters needs beyond what
    the process holds (:data:`WORK`)."""
    fixed, per_param = WORK[work]
    return int(n_poses * (fixed + per_param * n_params)) + RESERVE_BYTES


def available_bytes() -> tuple[int | None, str]:
    """(bytes this process may still allocate, what limits it); (None, "") when the
    system does not say."""
    limits: list[tuple[int, str]] = []
    mem = _meminfo_available()
    if mem is not None:
        limits.append((mem, "the memory available"))
    cg = _cgroup_room()
    if cg is not None:
        limits.append((cg, "the control group's memory limit"))
    room = _address_space_room()
    if room is not None:
        limits.append((room, "the address-space limit (ulimit -v)"))
    if not limits:
        return None, ""
    return min(limits)


def check_memory(what: str, work: str, n_poses: int, n_params: int) -> None:
    """Refuse (:class:`~calibration.errors.TooLarge`, exit 3) ``what`` over ``n_poses``
    when it would need more memory than :func:`available_bytes` leaves."""
    need = need_bytes(work, n_poses, n_params)
    have, why = available_bytes()
    if have is None or need <= have:
        return
    fixed, per_param = WORK[work]
    fits = max(int((have - RESERVE_BYTES) // (fixed + per_param * n_params)), 0)
    raise TooLarge(
        f"{what} of {n_poses:,} poses ({n_params} parameters) needs about "
        f"{_gib(need)} of memory; {_gib(have)} is left ({why}): at most about "
        f"{_round_down(fits):,} poses fit. Split the data (e.g. by date or by region of the "
        "workspace) or run where there is more memory")


def _gib(n: int) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def _round_down(n: int) -> int:
    """``n`` to two significant digits, down."""
    if n < 100:
        return n
    step = 10 ** (int(math.log10(n)) - 1)
    return n // step * step


def _meminfo_available() -> int | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _cgroup_room() -> int | None:
    """``memory.max - memory.current`` of this process's control group (v2), if limited."""
    try:
        rel = next(line.split(":", 2)[2] for line in
                   Path("/proc/self/cgroup").read_text().splitlines() if line.startswith("0::"))
        folder = Path("/sys/fs/cgroup") / rel.strip().lstrip("/")
        limit = (folder / "memory.max").read_text().strip()
        if limit == "max":
            return None
        return int(limit) - int((folder / "memory.current").read_text())
    except (OSError, ValueError, StopIteration, IndexError):
        return None


def _address_space_room() -> int | None:
    """``RLIMIT_AS`` less the process's address space now, when a limit is set."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft == resource.RLIM_INFINITY:
            return None
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmSize:"):
                return soft - int(line.split()[1]) * 1024
        return None
    except (ImportError, OSError, ValueError):
        return None
