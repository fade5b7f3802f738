"""The fault spec language and injector."""

from __future__ import annotations

import pytest

from sim_drivers.faults import FaultInjector, FaultSpec


def test_parse_probabilities_schedule_and_delay():
    spec = FaultSpec.parse(" beam=0.05, slow=0.02 ,drop@3,drop@7,delay=1.5,modbus=1")
    assert spec.probability == {"beam": 0.05, "slow": 0.02, "modbus": 1.0}
    assert spec.schedule == {"drop": {3, 7}}
    assert spec.delay_s == 1.5
    assert FaultSpec.parse("").probability == {}
    assert FaultSpec.parse(None).schedule == {}


@pytest.mark.parametrize(
    "text, match",
    [
        ("laser=0.1", "unknown fault 'laser'"),
        ("beam=2", r"probability must be in \[0, 1\]"),
        ("beam=x", "must be a number"),
        ("drop@x", "must be an integer"),
        ("drop@0", "< 1"),
        ("beam", "expected NAME=P"),
        ("delay=-1", "delay must be > 0"),
    ],
)
def test_parse_errors_name_the_entry(text, match):
    with pytest.raises(ValueError, match=match):
        FaultSpec.parse(text)


def test_schedule_arm_and_probability():
    f = FaultInjector("drop@2,beam=1")
    fired = []
    for _ in range(3):
        f.begin_command()
        fired.append((f.fires("drop"), f.fires("beam"), f.fires("slow")))
    assert fired == [(False, True, False), (True, True, False), (False, True, False)]
    f.arm("slow", times=2)
    f.begin_command()
    assert f.fires("slow") and f.fires("slow") and not f.fires("slow")
    with pytest.raises(ValueError):
        f.arm("nonsense")


def test_probability_is_seeded():
    def run(seed):
        f = FaultInjector("garbage=0.3", seed=seed)
        out = []
        for _ in range(50):
            f.begin_command()
            out.append(f.fires("garbage"))
        return out

    assert run(4) == run(4)
    assert 5 < sum(run(4)) < 25
