"""The ROS 1 backend of the hardware seam (``robots.agent.hardware``), on Debian's ROS 1
packages (``ros-core``, ``python3-rospy``, ``python3-actionlib``, ``python3-move-base-msgs``).

Debian installs them for the system's Python 3 in ``/usr/lib/python3/dist-packages``;
``ros_path()`` puts that directory at the end of ``sys.path`` of a virtualenv of the same
Python minor version, so the virtualenv's own packages (numpy, OpenCV) still win.
"""

from __future__ import annotations

import importlib.util
import sys

DEBIAN_DIST_PACKAGES = "/usr/lib/python3/dist-packages"


def ros_path() -> bool:
    """Make rospy importable (appending Debian's dist-packages when needed); whether it is."""
    if importlib.util.find_spec("rospy") is None and DEBIAN_DIST_PACKAGES not in sys.path:
        sys.path.append(DEBIAN_DIST_PACKAGES)
    return importlib.util.find_spec("rospy") is not None
