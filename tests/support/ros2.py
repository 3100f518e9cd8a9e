"""The ROS 2 installs the ROS 2 tests run against (the ``ros2_venv`` fixture, a pytest
plugin of tests/conftest.py)."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import ros2_bridge


@pytest.fixture(scope="session", params=["jazzy", "kilted"])
def ros2_venv(request: pytest.FixtureRequest) -> Path:
    """The ROS 2 virtualenv of the distro, built by ``scripts/ros2_env.sh`` (cached)."""
    try:
        return ros2_bridge.ros2_venv(request.param)
    except RuntimeError as failed:
        pytest.fail(str(failed))
