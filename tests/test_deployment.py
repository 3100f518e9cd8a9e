"""Outside the demo and the tests, the server refuses the public default SECRET_KEY, and
``testserver`` is not an allowed host."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def load_server(**env: str) -> subprocess.CompletedProcess[str]:
    """Import the ASGI application as a server would, with the plain settings and ``env``."""
    environment = {k: v for k, v in os.environ.items() if k not in ("SECRET_KEY", "CLOUDNAV_DEMO")}
    environment.update(DJANGO_SETTINGS_MODULE="cloudnav_web.settings", **env)
    return subprocess.run(
        [sys.executable, "-c", "import cloudnav_web.asgi"],
        cwd=ROOT,
        env=environment,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_server_refuses_the_demo_key_outside_the_demo() -> None:
    done = load_server()
    assert done.returncode != 0
    assert "SECRET_KEY is the public demo key" in done.stderr


@pytest.mark.parametrize("env", [{"CLOUDNAV_DEMO": "1"}, {"SECRET_KEY": "s" * 50}])
def test_the_server_starts_in_the_demo_or_with_a_key_of_its_own(env: dict[str, str]) -> None:
    done = load_server(**env)
    assert done.returncode == 0, done.stderr


def test_testserver_is_not_an_allowed_host_outside_tests() -> None:
    code = "from cloudnav_web import settings; print(settings.ALLOWED_HOSTS)"
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert "testserver" not in done.stdout
    assert "127.0.0.1" in done.stdout
