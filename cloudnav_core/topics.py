"""A robot's topics and services: their names, relative to the robot's namespace, and their
types. The robot side and the server both read them here (docs/design.md lists them)."""

from __future__ import annotations

# The server's own service namespaces: called by relative name from any connection and
# advertised by none, so no robot may be named after one.
ROSAPI = "/rosapi"
CLOUDNAV = "/cloudnav"
GLOBAL_NAMESPACES = frozenset({ROSAPI.strip("/"), CLOUDNAV.strip("/")})

# Topics of each robot, relative to its namespace, with their message types (docs/design.md).
ROBOT_TOPIC_TYPES = {
    "pose": "geometry_msgs/PoseStamped",
    "odom": "nav_msgs/Odometry",
    "scan": "sensor_msgs/LaserScan",
    "plan": "nav_msgs/Path",
    "nav_status": "actionlib_msgs/GoalStatusArray",
    "map_id": "std_msgs/String",
    "localisation": "diagnostic_msgs/DiagnosticStatus",
    "battery": "sensor_msgs/BatteryState",
    "camera/image/compressed": "sensor_msgs/CompressedImage",
    "camera/depth/image/compressedDepth": "sensor_msgs/CompressedImage",
    "camera/depth/image": "sensor_msgs/Image",
    "camera/camera_info": "sensor_msgs/CameraInfo",
    "cmd_vel": "geometry_msgs/Twist",
    "goal": "geometry_msgs/PoseStamped",
    "initialpose": "geometry_msgs/PoseWithCovarianceStamped",
    # Published by the server (latched): the robot's mapping session changed or saved its map.
    "mapping": "std_msgs/String",
    # Published by the server (latched): wait before a narrow place, or go (docs/design.md).
    "right_of_way": "std_msgs/String",
}
# Services each robot serves, relative to its namespace, with their types: operators may
# call them (a robot's goal is cancelled by a call, since operators publish only commands).
CANCEL_GOAL = "cancel_goal"
ROBOT_SERVICE_TYPES = {CANCEL_GOAL: "std_srvs/Trigger"}
# What operators may publish to a robot they may drive.
COMMAND_TOPICS = frozenset({"cmd_vel", "goal", "initialpose"})
# Topics whose last message every new subscriber receives, whatever the publisher asked.
LATCHED_TOPICS = frozenset({"map_id", "localisation", "mapping", "right_of_way"})
# Robot topics only the server publishes: the robot itself may not.
SERVER_TOPICS = frozenset({"mapping", "right_of_way"})
CMD_VEL = "cmd_vel"
POSE = "pose"
MAP_ID = "map_id"
NAV_STATUS = "nav_status"
LOCALISATION = "localisation"
BATTERY = "battery"
MAPPING = "mapping"
RIGHT_OF_WAY = "right_of_way"
PLAN = "plan"
GOAL = "goal"
ODOM = "odom"
SCAN = "scan"
CAMERA_IMAGE = "camera/image/compressed"
CAMERA_DEPTH = "camera/depth/image/compressedDepth"
CAMERA_INFO = "camera/camera_info"


def robot_topic(robot: str, suffix: str) -> str:
    """Return the absolute name of one of ``robot``'s topics, e.g. ``/r1/cmd_vel``."""
    return f"/{robot}/{suffix}"
