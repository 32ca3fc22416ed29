"""The simulator's clock slows down when the machine cannot keep up, and recovers."""

from __future__ import annotations

import pytest

import coffeebot.clock
from coffeebot.clock import ScaledClock
from coffeebot.sim.simulation import Pacer


def test_rate_change_keeps_time_continuous_and_monotonic() -> None:
    clock = ScaledClock(speed=8.0, start=100.0)
    before = clock.now()
    clock.set_rate(2.0)
    after = clock.now()
    assert before <= after < before + 0.05
    assert clock.rate == 2.0


def test_rate_is_clamped_to_the_requested_speed() -> None:
    clock = ScaledClock(speed=4.0)
    clock.set_rate(10.0)
    assert clock.rate == 4.0
    clock.set_rate(0.0)
    assert 0 < clock.rate < 0.01


def test_a_late_loop_slows_the_clock_and_an_idle_one_speeds_it_back_up() -> None:
    clock = ScaledClock(speed=4.0)
    pacer = Pacer(clock, max_lag_s=0.01)
    for _ in range(200):  # every step wakes 30 ms (simulated) late
        pacer.observe(0.03)
    slowed = clock.rate
    assert slowed < 4.0 * 0.85
    for _ in range(2000):  # on time again
        pacer.observe(0.0)
    assert clock.rate == 4.0


def test_occasional_late_steps_do_not_slow_the_clock() -> None:
    clock = ScaledClock(speed=4.0)
    pacer = Pacer(clock, max_lag_s=0.01)
    for k in range(1000):  # one step in 20 is 50 ms late: a hiccup, not a trend
        pacer.observe(0.05 if k % 20 == 0 else 0.001)
    assert clock.rate == 4.0


def test_simulated_time_stands_still_while_the_world_computes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    real = [0.0]
    monkeypatch.setattr(coffeebot.clock.time, "monotonic", lambda: real[0])
    clock = ScaledClock(speed=100.0)
    real[0] = 0.01
    assert clock.now() == pytest.approx(1.0)
    with clock.hold():
        real[0] = 0.03  # two simulated seconds, were the clock running
        assert clock.now() == pytest.approx(1.0)
        with clock.hold():  # another thread's hold, overlapping
            real[0] = 0.04
        assert clock.now() == pytest.approx(1.0)
    real[0] = 0.05
    assert clock.now() == pytest.approx(2.0)  # running again, from where it stood
