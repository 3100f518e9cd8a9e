"""The checks that keep the map file builders (tests/support/mapfiles.py) honest: they
compute a pixel's occupancy exactly as the rule states."""

from __future__ import annotations

import numpy as np

from tests.support.mapfiles import float32_step, occupancy_of


def test_occupancy_of_matches_the_rule_in_float32() -> None:
    assert occupancy_of(89) == float(np.float32(1) - np.float32(89) / np.float32(255))
    assert occupancy_of(89, negate=True) == float(np.float32(89) / np.float32(255))


def test_float32_step_gives_the_adjacent_float32() -> None:
    p = occupancy_of(89)
    above = float32_step(p, 1)
    assert np.float32(above) > np.float32(p)
    assert np.nextafter(np.float32(p), np.float32(1)) == np.float32(above)
    assert float32_step(above, -1) == p
