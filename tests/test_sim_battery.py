"""The simulated battery drains while driving, a little while waiting, never below empty."""

from __future__ import annotations

from robots.agent.sim.battery import EMPTY_VOLTAGE, FULL_VOLTAGE, SimBattery


def test_driving_drains_the_battery_faster_than_waiting() -> None:
    driving, waiting = SimBattery(), SimBattery()
    driving.drain(60.0, 0.5, 0.2)
    waiting.drain(60.0, 0.0, 0.0)
    assert driving.charge < waiting.charge < 1.0


def test_an_empty_battery_stays_empty_at_its_lowest_voltage() -> None:
    battery = SimBattery(charge=0.01)
    battery.drain(3600.0, 1.0, 0.0)
    assert battery.charge == 0.0
    assert battery.voltage == EMPTY_VOLTAGE
    assert SimBattery().voltage == FULL_VOLTAGE
