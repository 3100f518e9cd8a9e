"""A private ``roscore`` on a free port, for the bridge's measurements (Debian's ROS 1)."""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextlib.contextmanager
def private_roscore(deadline: float = 60.0) -> Iterator[dict[str, str]]:
    """Start ``roscore`` on a free port and wait until it answers; yields the environment
    that reaches it (also set in ``os.environ``, for this process's node). Raises
    TimeoutError if it does not answer within ``deadline`` seconds."""
    import rosgraph  # type: ignore[import-not-found,unused-ignore]

    port = free_port()
    os.environ.update(
        ROS_MASTER_URI=f"http://127.0.0.1:{port}",
        ROS_HOSTNAME="127.0.0.1",
        ROS_HOME=tempfile.mkdtemp(prefix="cloudnav-ros-"),
    )
    core = subprocess.Popen(
        ["roscore", "-p", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        master, give_up = rosgraph.Master("/probe"), time.monotonic() + deadline
        while not _answers(master):
            if time.monotonic() > give_up or core.poll() is not None:
                raise TimeoutError("roscore did not start")
            time.sleep(0.1)
        yield dict(os.environ)
    finally:
        core.terminate()
        core.wait(timeout=30)


def _answers(master: object) -> bool:
    try:
        master.getPid()  # type: ignore[attr-defined]
    except OSError:
        return False
    return True
