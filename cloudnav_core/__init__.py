"""The robotics core below every app and the robot side: plain Python, no Django.

What the server and the robot share has one home here: the planar geometry (``se2``), a
robot's parameters (``params``), occupancy grids (``grid``), the camera (``camera``), the
ROS messages with their readers (``messages``), their times (``times``), the cameras'
time code (``timecode``), a robot's topics and services (``topics``), and the one way to
run background work (``workers``: bounded inboxes with a named drop policy, named
workers stopped and joined at shutdown). Nothing here imports maps, robots, telemetry,
cloudnav_django or cloudnav_web: the core is the bottom layer (import-linter,
pyproject.toml).
"""
