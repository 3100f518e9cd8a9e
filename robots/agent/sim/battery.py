"""A simulated battery that drains while the robot drives, and a little while it waits."""

from __future__ import annotations

from dataclasses import dataclass

# Fraction of a full charge spent per metre driven, per radian turned and per idle second:
# a full battery drives about 250 m, or waits about 14 hours.
PER_METRE = 0.004
PER_RADIAN = 0.0005
PER_SECOND = 0.00002
FULL_VOLTAGE = 12.6
EMPTY_VOLTAGE = 10.5


@dataclass
class SimBattery:
    """``charge`` is the fraction left, 0..1."""

    charge: float = 1.0

    def drain(self, seconds: float, linear: float, angular: float) -> None:
        """Spend what ``seconds`` at velocity (``linear`` m/s, ``angular`` rad/s) costs."""
        spent = seconds * (PER_SECOND + PER_METRE * abs(linear) + PER_RADIAN * abs(angular))
        self.charge = max(0.0, self.charge - spent)

    @property
    def voltage(self) -> float:
        return EMPTY_VOLTAGE + (FULL_VOLTAGE - EMPTY_VOLTAGE) * self.charge
