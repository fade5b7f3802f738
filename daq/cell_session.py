"""One session at the cell: the devices reached, known, checked and held, before a run moves.

A start, a resume and a resume in another cell all open the cell the same way
(:func:`cell_session`)::

    with cell_session(store, model, robot_url, tracker_url, setup, options,
                      confirm=confirm) as session:
        frame = session.frame_run(None, robot_id)
        run_id = session.create_run(plan, context, robot_id=robot_id)
        execute(store, run_id, plan, session.robot, session.tracker, ...)

The steps, in this order: the robot's lease (:mod:`daq.store.leases`; on resume the run's
first), connect (:func:`daq.devices.devices`), ask who the devices are
(:func:`daq.devices.identify`), check the robot against the model
(:func:`daq.devices.check_robot`), the robot's lease by its serial number, then

- a start: the tracker's checks (:func:`daq.tracker_checks.check_tracker`, two faces
  included), then the caller's ``confirm``;
- a resume (``resumed``): the devices must be the run's cell (:func:`daq.devices.same_cell`,
  else :class:`OtherCell` unless ``other_cell``), the caller's ``confirm``, then the
  tracker's checks without the two faces. A failed connection is recorded with the run
  (``connection``) before :class:`~daq.errors.ConnectFailed` propagates, a refused tracker
  likewise (``not_ready``) before :class:`~daq.errors.TrackerRefused`.

Nothing is stored before the block's body runs; the session's leases are released and
the devices it connected closed when the block ends.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from drivers.errors import DriverError
from drivers.protocols import ReflectorSelect

from .devices import (
    CellIdentity,
    check_robot,
    describe,
    identify,
    same_cell,
    stored_identity,
)
from .devices import devices as reach_devices
from .errors import ConnectFailed, RequestError, TrackerRefused
from .plans import Plan
from .run_context import ExecutorOptions, RunContext, TrackerCheck, TrackerSetup
from .store import InterruptionKind, Run, RunStore, StoreError, StoreUnavailable
from .store.leases import Leases, held_leases, run_key, take_robot
from .store.queries import frame_run, measured_in
from .tracker_checks import check_tracker

log = logging.getLogger(__name__)

#: called with the devices' identities before anything moves; raises to refuse
ConfirmFn = Callable[[CellIdentity, str, str], None]


class OtherCell(RequestError):
    """The devices reached are not the run's cell (resume without ``other_cell``)."""


@dataclass(frozen=True)
class CellSession:
    """The cell as :func:`cell_session` opened it: the connected ``robot`` and ``tracker``,
    who they said they were (``cell``), the ``held`` leases, what the tracker's checks
    found (``tracker_check``) and, on a resume in another cell, why it is another
    (``elsewhere``; empty in the run's own cell)."""

    store: RunStore
    robot_url: str
    tracker_url: str
    robot: object
    tracker: object
    cell: CellIdentity
    held: Leases
    tracker_check: TrackerCheck
    elsewhere: str = ""

    def frame_run(self, run_id: int | None, robot_id: str | None) -> Run | None:
        """The measurement frame's run for this cell: ``run_id``, else the latest completed
        frame run of this cell and robot (:func:`daq.store.queries.frame_run`); None
        without one. :class:`RequestError` for a run that is no frame run or was measured
        in another cell."""
        try:
            frame = frame_run(self.store, run_id, self.cell, robot_id, self.robot_url)
        except StoreUnavailable:
            raise
        except StoreError as e:
            raise RequestError(str(e)) from None
        if frame is not None and not measured_in(frame, self.cell):
            raise RequestError(f"frame run {frame.id} was measured in another cell (robot "
                               f"{stored_identity(frame.robot_identity)}, tracker "
                               f"{stored_identity(frame.tracker_identity)}): its frame "
                               "does not hold here")
        return frame

    def create_run(self, plan: Plan, context: RunContext, *, robot_id: str | None,
                   source_run: int | None = None) -> int:
        """Store a new run of ``plan`` with the devices' descriptions and identities, and
        hold its lease for the rest of the session; its id."""
        run_id = self.store.create_run(plan, context, robot_desc=describe(self.robot),
                                       tracker_desc=describe(self.tracker),
                                       robot_identity=self.cell.robot.to_dict(),
                                       tracker_identity=self.cell.tracker.to_dict(),
                                       source_run=source_run, robot_id=robot_id)
        self.held.acquire(run_key(run_id), f"run {run_id}")
        return run_id

    def reflector_context(self, smr_radius_mm: float | None = None) -> dict:
        """``smr_radius_mm`` and ``reflector`` for the run context: the given radius, else
        the surface offset of the reflector the tracker reports (trackers with the
        :class:`~drivers.protocols.ReflectorSelect` capability); None where unknown."""
        out = {"smr_radius_mm": smr_radius_mm, "reflector": None}
        if isinstance(self.tracker, ReflectorSelect):
            try:
                r = self.tracker.reflector()
            except DriverError:
                return out
            out["reflector"] = r.name or None
            if smr_radius_mm is None and r.surface_offset_mm > 0:
                out["smr_radius_mm"] = float(r.surface_offset_mm)
        return out


def frame_fields(frame: Run | None) -> dict:
    """The run context's ``frame_run`` and ``tracker_T_base`` of a frame run (None: none)."""
    return {"frame_run": None if frame is None else frame.id,
            "tracker_T_base": None if frame is None else frame.frame["tracker_T_base"]}


@contextlib.contextmanager
def cell_session(store: RunStore, model, robot_url: str, tracker_url: str,
                 setup: TrackerSetup, options: ExecutorOptions, *,
                 devices: tuple | None = None, leases: Leases | None = None,
                 confirm: ConfirmFn | None = None, resumed: Run | None = None,
                 other_cell: bool = False) -> Iterator[CellSession]:
    """Open the cell for a run (the steps: the module's docstring).

    Parameters
    ----------
    store : RunStore
    model : RobotModel
        The run's model, which the robot must fit.
    robot_url, tracker_url : str
        The devices (connected unless ``devices`` is given).
    setup : TrackerSetup
        The tracker's setup and checks.
    options : ExecutorOptions
        Its ``connect_timeout_s`` and ``io_timeout_s`` are used here.
    devices : (robot, tracker), optional
        Already connected drivers (left open).
    leases : Leases, optional
        Where the leases are held (default: the session's own, released at its end).
    confirm : callable(cell identity, robot_url, tracker_url), optional
        Called before anything moves or is stored; raises to refuse.
    resumed : Run, optional
        The stored run being resumed: its lease is taken first, the devices are compared
        with its cell, failures are recorded with it.
    other_cell : bool
        With ``resumed``: another cell is accepted (``session.elsewhere`` says why it is
        another) instead of refused with :class:`OtherCell`.
    """
    def connect_failed(e: ConnectFailed) -> None:
        store.add_interruption(resumed.id, None, InterruptionKind.CONNECTION,
                               f"resume: cannot connect: {e}")

    with held_leases(store, leases) as held:
        if resumed is not None:
            held.acquire(run_key(resumed.id), f"run {resumed.id}")
        take_robot(held, robot_url)
        with reach_devices(robot_url, tracker_url, devices, options.connect_timeout_s,
                           on_fail=None if resumed is None else connect_failed
                           ) as (robot, tracker):
            cell = identify(robot, tracker, options.io_timeout_s + 1.0)
            log.info("devices: robot %s is %s; tracker %s is %s", robot_url,
                     cell.robot.to_dict(), tracker_url, cell.tracker.to_dict())
            check_robot(model, robot, cell.robot)
            take_robot(held, robot_url, cell.robot)
            if resumed is None:
                found = check_tracker(tracker, setup, options)
                if confirm is not None:
                    confirm(cell, robot_url, tracker_url)
                why = ""
            else:
                why = _other_cell(resumed, cell, robot_url, tracker_url, other_cell)
                if confirm is not None:
                    confirm(cell, robot_url, tracker_url)
                try:
                    found = check_tracker(tracker, setup, options, two_face=False)
                except TrackerRefused as e:
                    store.add_interruption(resumed.id, None, InterruptionKind.NOT_READY,
                                           f"resume: {e}")
                    raise
            log.info("tracker checked: %s", found.model_dump_json(exclude_none=True))
            yield CellSession(store, robot_url, tracker_url, robot, tracker, cell, held,
                              found, why)


def _other_cell(run: Run, cell: CellIdentity, robot_url: str, tracker_url: str,
                accept: bool) -> str:
    """Why the devices reached are not ``run``'s cell ("" when they are); :class:`OtherCell`
    unless ``accept``."""
    same, why = same_cell(run, cell, robot_url, tracker_url)
    if same:
        return ""
    if not accept:
        raise OtherCell(f"run {run.id} was measured in another cell: {why}. Resume it with "
                        "its own robot and tracker, or pass --other-cell to start a new run "
                        "of the same plan with these (the two cells' samples are never "
                        "mixed)")
    return why
