"""The driver contract, checked on the classes: every driver's methods have its protocols'
signatures (names, kinds, defaults), a capability is offered whole or not at all, and
every driver the package offers is in the conformance suite."""

from __future__ import annotations

import importlib
import inspect

import pytest

import drivers
from drivers import protocols as P
from tests.drivers.rigs import ROBOTS, TRACKERS

#: what a driver must implement whole, by its role
ROLES = {"robot": P.RobotDriver, "tracker": P.TrackerDriver}
#: optional capabilities: all of their methods, or none
CAPABILITIES = (P.Identified, P.JointTemperatures, P.CommandedPosition, P.ReadyGate,
                P.EnvironmentSensor, P.ReflectorSelect, P.SixDof, P.TwoFace)

SUITE = {**{k.cls: "robot" for k in ROBOTS.values()},
         **{k.cls: "tracker" for k in TRACKERS.values()}}


def _methods(proto) -> list[str]:
    return [n for n, v in vars(proto).items() if inspect.isfunction(v) and not n.startswith("_")]


def _shape(fn) -> list[tuple[str, object, object]]:
    """Parameter names, kinds and defaults (annotations aside)."""
    return [(p.name, p.kind, p.default) for p in inspect.signature(fn).parameters.values()]


def _problems(cls, proto, required: bool) -> list[str]:
    names = _methods(proto)
    have = [n for n in names if callable(getattr(cls, n, None))]
    if not have and not required:
        return []
    out = [f"{proto.__name__}.{n} missing" for n in names if n not in have]
    for n in have:
        want, got = _shape(getattr(proto, n)), _shape(getattr(cls, n))
        if want != got:
            out.append(f"{proto.__name__}.{n}{inspect.signature(getattr(proto, n))} but "
                       f"{cls.__name__}.{n}{inspect.signature(getattr(cls, n))}")
    return out


@pytest.mark.parametrize("cls", list(SUITE), ids=lambda c: c.__name__)
def test_every_method_has_the_protocols_signature(cls):
    problems = _problems(cls, ROLES[SUITE[cls]], required=True)
    for cap in CAPABILITIES:
        problems += _problems(cls, cap, required=False)
    assert not problems, "\n".join(problems)


def test_the_check_sees_a_drifted_driver():
    class Drifted:
        url = ""

        def connect(self, timeout: float = 5.0) -> None: ...

        def close(self) -> None: ...

        def read_joints(self, timeout: float = 1.0): ...

        def move_joints(self, q, speed: float = 0.5, timeout: float = 60.0, *, wait=False): ...

        def move_linear(self, xyz, speed: float = 100.0, timeout: float = 30.0): ...

        def wait_settled(self, timeout: float = 30.0) -> None: ...

        def status(self, t: float = 1.0): ...

        def stop(self, timeout: float = 2.0) -> None: ...

        def face(self, timeout: float = 2.0) -> int: ...

    problems = _problems(Drifted, P.RobotDriver, required=True)
    assert [p.split("(")[0] for p in problems] == [
        "RobotDriver.move_joints", "RobotDriver.move_linear", "RobotDriver.status"]
    assert _problems(Drifted, P.TwoFace, required=False) == [
        "TwoFace.change_face missing", "TwoFace.measure_faces missing"]


def test_every_driver_of_the_package_is_in_the_suite():
    offered = {getattr(importlib.import_module(module), name)
               for name, module in drivers._LAZY.items() if module != "drivers.protocols"}
    offered = {c for c in offered if any(callable(getattr(c, m, None))
                                         for m in ("move_joints", "measure"))}
    assert offered and offered <= set(SUITE), offered - set(SUITE)
    for cls, role in SUITE.items():
        assert isinstance(cls, type) and issubclass(cls, object)
        assert all(callable(getattr(cls, m, None)) for m in _methods(ROLES[role])), cls
