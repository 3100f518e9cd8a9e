"""The robot side installs by itself: ``robots/agent/requirements.txt`` in a fresh virtualenv
(no Django, Channels or DRF) gives a working ``python -m robots.agent``.

The virtualenv is built from PyPI (pip's cache makes it quick after the first time); set
``CLOUDNAV_WHEELHOUSE`` to a directory of wheels (``pip download -d DIR -r
robots/agent/requirements.txt``) to build it offline with ``--no-index --find-links``.
"""

from __future__ import annotations

import os
import re
import subprocess
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
AGENT_REQUIREMENTS = ROOT / "robots" / "agent" / "requirements.txt"
SERVER_ONLY = ("django", "channels", "rest_framework", "daphne", "drf_spectacular")

# Imports every module of the agent, then proves no server framework is loaded or installed.
IMPORT_CHECK = """
import importlib, importlib.util, pkgutil, sys
import robots.agent
names = [m.name for m in pkgutil.walk_packages(robots.agent.__path__, "robots.agent.")]
ros = ("robots.agent.ros.", "robots.agent.sim.ros_nodes")  # need ROS 1 installed
ros += ("robots.agent.ros2.", "robots.agent.sim.ros2_nodes")  # rclpy (scripts/ros2_env.sh)
names = [n for n in names if not n.startswith(ros)]
for name in names:
    importlib.import_module(name)
server = [n for n in {server!r} if n in sys.modules or importlib.util.find_spec(n)]
assert not server, f"server packages present: {{server}}"
print(len(names), "modules")
"""


def pins(path: Path) -> dict[str, str]:
    found = {}
    for line in path.read_text().splitlines():
        match = re.match(r"^([A-Za-z0-9_.\-]+)==(\S+)", line.strip())
        if match:
            found[match[1].lower().replace("_", "-")] = match[2]
    return found


def test_agent_pins_equal_the_servers() -> None:
    agent, server = pins(AGENT_REQUIREMENTS), pins(ROOT / "requirements.txt")
    assert agent, "robots/agent/requirements.txt pins nothing"
    assert {name: server.get(name) for name in agent} == agent
    assert not set(agent) & {name.replace("_", "-") for name in SERVER_ONLY}


@pytest.fixture(scope="module")
def agent_python(tmp_path_factory: pytest.TempPathFactory) -> Path:
    home = tmp_path_factory.mktemp("agent-venv")
    venv.EnvBuilder(with_pip=True, clear=True).create(home)
    python = home / ("Scripts" if os.name == "nt" else "bin") / "python"
    install = [str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    wheelhouse = os.environ.get("CLOUDNAV_WHEELHOUSE")
    if wheelhouse:
        install += ["--no-index", "--find-links", wheelhouse]
    done = subprocess.run(
        [*install, "-r", str(AGENT_REQUIREMENTS)], capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return python


def run_in(python: Path, *args: str) -> subprocess.CompletedProcess[str]:
    # Only the repository on the path: nothing of the server's virtualenv leaks in.
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PYTHONPATH"] = str(ROOT)
    return subprocess.run(
        [str(python), *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )


@pytest.mark.slow
def test_fresh_virtualenv_runs_the_agent(agent_python: Path) -> None:
    helped = run_in(agent_python, "-m", "robots.agent", "--help")
    assert helped.returncode == 0, helped.stderr
    assert "--server" in helped.stdout
    assert "--token" in helped.stdout

    checked = run_in(agent_python, "-c", IMPORT_CHECK.format(server=SERVER_ONLY))
    assert checked.returncode == 0, checked.stderr
    assert checked.stdout.strip().endswith("modules")
