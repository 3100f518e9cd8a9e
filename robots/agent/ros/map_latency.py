"""``python -m robots.agent.ros.map_latency [ROWSxCOLS]``: how long a new sub-map takes
from ``RosNavigationStack.set_map`` to a ``/map`` subscriber's callback, on a private
``roscore`` this starts (Debian's ROS 1). Prints the median and the worst of 20 maps."""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from robots.agent.ros import ros_path
from robots.agent.ros.master import private_roscore


def measure(rows: int, cols: int, maps: int = 20) -> list[float]:
    """Milliseconds from ``set_map`` to the subscriber holding it, one per map."""
    import rospy  # type: ignore[import-not-found,unused-ignore]
    from nav_msgs.msg import OccupancyGrid  # type: ignore[import-not-found,unused-ignore]

    from robots.agent.ros.navigation import RosNavigationStack

    rospy.init_node("cloudnav_map_latency", disable_signals=True)
    arrived: list[float] = []
    rospy.Subscriber("/map", OccupancyGrid, lambda _msg: arrived.append(time.perf_counter()))
    stack = RosNavigationStack()
    grid = np.zeros((rows, cols), dtype=np.int8)
    while stack.map_subscribers() == 0:  # the subscriber has connected
        time.sleep(0.01)
    times = []
    for index in range(maps):
        seen, start = len(arrived), time.perf_counter()
        stack.set_map(f"bench/map{index}", grid, 0.05, (0.0, 0.0, 0.0))
        while len(arrived) == seen:
            time.sleep(0.0005)
        times.append((arrived[-1] - start) * 1000)
    rospy.signal_shutdown("measured")
    return times


def main(argv: list[str]) -> None:
    rows, cols = (int(n) for n in (argv[0] if argv else "312x120").split("x"))
    if not ros_path():
        raise SystemExit("ROS 1 is not installed (scripts/setup.sh installs it)")
    with private_roscore():
        times = measure(rows, cols)
    print(
        f"{rows}x{cols} grid, set_map -> /map subscriber: median "
        f"{statistics.median(times):.1f} ms, worst {max(times):.1f} ms ({len(times)} maps)"
    )


if __name__ == "__main__":
    main(sys.argv[1:])
