"""Template filters that show quantities to people in their units: angles in degrees
(poses and origins are stored and sent in radians, as ROS has them)."""

from __future__ import annotations

import math

from django import template

register = template.Library()


@register.filter
def degrees(radians: float | None) -> str:
    """``1.5708`` -> ``"90°"``; an empty string for no value."""
    if radians is None:
        return ""
    value = round(math.degrees(float(radians)))
    return f"{0 if value == 0 else value}°"  # never "-0°"
