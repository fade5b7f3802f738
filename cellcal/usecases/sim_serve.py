"""``cellcal sim serve``: the simulated cell behind its wire protocols, until stopped.

:class:`SimServeRequest` is what the user asked (the true robot, its hidden effects, the
tracker, the ports); :func:`serve_cell` checks it, starts the servers, hands their URLs
to ``on_ready`` and serves until ``stop`` is set (or Ctrl-C), then stops them cleanly.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Annotated, Any, Self

from pydantic import Field

from ..errors import UsageError
from ..flags.sim_ports import ABB_PORT, DEFAULT_PORTS, PORT_FLAGS
from ..request import Request
from .capture import Point, comma_numbers


def ports_of(args) -> dict[str, int]:
    """The ports asked for: the defaults, or from --port-base, then the port flags."""
    out = {**DEFAULT_PORTS, "abb": ABB_PORT}
    if args.port_base is not None:
        out = {name: args.port_base + k if args.port_base else 0
               for k, name in enumerate([*DEFAULT_PORTS, "abb"])}
    for name in DEFAULT_PORTS:
        v = getattr(args, PORT_FLAGS[name].lstrip("-").replace("-", "_"))
        if v is not None:
            out[name] = v
    if getattr(args, "abb_port", None) is not None:
        out["abb"] = args.abb_port
    bad = {name: v for name, v in out.items() if not 0 <= v <= 65535}
    if bad:
        raise UsageError("ports must be 0..65535 (0: any free port), got "
                         + ", ".join(f"{k} {v}" for k, v in bad.items()))
    return out


class SimServeRequest(Request):
    """The simulated cell to serve: the true robot (``model``, ``toy``: the 3-joint arm),
    its hidden effects and faults, the tracker (where it stands, the cell, its weather
    station, collimation error and warm-up), and where to listen."""

    seed: int = Field(0, alias="--seed")
    model: str = Field("ur10e", alias="--model")
    tracker_at: Annotated[Point | None, comma_numbers(3)] = Field(None, alias="--tracker-at")
    cell: str | None = Field(None, alias="--cell")
    hidden: str | None = Field(None, alias="--hidden")
    faults: str | None = Field(None, alias="--faults")
    thermal: str | None = Field(None, alias="--thermal")
    time_scale: float = Field(0.0, alias="--time-scale")
    host: str = Field("127.0.0.1", alias="--host")
    ports: dict[str, int] = {}
    any_port: bool = Field(False, alias="--any-port")
    no_pty: bool = Field(False, alias="--no-pty")
    abb: bool = Field(False, alias="--abb")
    no_rtde: bool = Field(False, alias="--no-rtde")
    no_weather_station: bool = Field(False, alias="--no-weather-station")
    tracker_collimation_urad: float = Field(0.0, alias="--tracker-collimation-urad")
    tracker_warmup_s: float = Field(0.0, alias="--tracker-warmup-s")
    six_dof: Annotated[Point | None, comma_numbers(3)] = Field(None, alias="--six-dof")

    @classmethod
    def from_args(cls, args: Any, **given: Any) -> Self:
        """The request of ``cellcal sim serve``'s arguments, the ports resolved."""
        return super().from_args(args, ports=ports_of(args), **given)


def _check_hidden(req: SimServeRequest) -> None:
    if req.hidden and req.model != "toy":
        from calibration import EffectError, load_model, parse_effects

        model = load_model(req.model)  # a bad model: ModelError, exit 2
        try:
            parse_effects(req.hidden, model)
        except EffectError as e:
            raise UsageError(f"--hidden {req.hidden!r}: {e}") from None


def sim_stack(req: SimServeRequest):
    """The simulated cell's servers (:class:`sim_drivers.serve.SimStack`), not started;
    UsageError for a bad model, hidden effect or cell."""
    from calibration.cell.cell import load_cell
    from sim_drivers.serve import ServeConfig, SimStack

    _check_hidden(req)
    config = ServeConfig(seed=req.seed, hidden=req.hidden, faults=req.faults,
                         time_scale=req.time_scale, thermal=req.thermal, host=req.host,
                         ports=req.ports,
                         pty=not req.no_pty, rtde=not req.no_rtde, any_port=req.any_port,
                         abb=req.abb)
    try:
        cell = load_cell(req.cell) if req.cell else None
    except ValueError as e:
        raise UsageError(str(e)) from None
    if req.model == "toy":
        from sim_drivers.inprocess import default_truth as factory
    else:
        from sim_drivers.model_truth import DEFAULT_TRACKER_AT_MM, ModelTruth

        at = req.tracker_at or (cell.tracker_mm if cell is not None and cell.tracker is not None
                                else DEFAULT_TRACKER_AT_MM)
        axis = (0.0, 0.0, 1.0) if cell is None else cell.smr.axis

        def factory(seed, hidden):
            return ModelTruth.from_spec(req.model, hidden, seed, tracker_at=at, smr_axis=axis)

    extra = {}
    if req.six_dof is not None:
        if req.model == "toy":
            raise UsageError("--six-dof needs a robot model (the toy arm has no flange "
                             "orientation)")
        if not all(math.isfinite(v) and abs(v) <= 360.0 for v in req.six_dof):
            raise UsageError(f"--six-dof {','.join(f'{v:g}' for v in req.six_dof)}: the "
                             "target's nominal orientation is a rotation vector of three "
                             "finite angles within +-360 deg")
        from sim_drivers.six_dof import SixDofTarget

        extra["six_dof"] = SixDofTarget.on_tool(tuple(req.six_dof), seed=req.seed)
    try:
        return SimStack(config, truth_factory=factory, cell=cell, **extra,
                        weather_station=not req.no_weather_station,
                        tracker_collimation_rad=req.tracker_collimation_urad * 1e-6,
                        warmup_s=req.tracker_warmup_s)
    except ValueError as e:  # ModelError and EffectError are ValueErrors too
        raise UsageError(str(e)) from e


def serve_cell(req: SimServeRequest, stop: threading.Event,
               on_ready: Callable[[list[str], list[str]], None]) -> None:
    """Serve the cell until ``stop`` is set or Ctrl-C: ``on_ready(urls, notes)`` once the
    servers listen. A port in use is a UsageError (unless ``req.any_port``)."""
    stack = sim_stack(req)
    try:
        stack.start()
    except ValueError as e:  # PortInUse
        raise UsageError(str(e)) from None
    try:
        on_ready(stack.urls, stack.notes)
        try:
            while not stop.wait(0.2):
                pass
        except KeyboardInterrupt:
            pass
    finally:
        stack.stop()
