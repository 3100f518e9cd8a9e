"""rosbridge_suite's own WebSocket tests (rosbridge_server/test/websocket), reproduced
against CloudNav over real sockets.

In the originals a ROS node stands on the other side of rosbridge; here the server has no
ROS graph, so a second rosbridge client plays that node. Names, frames, counts and
expected replies are theirs; admins play both sides because the names (``/a_topic``,
``/test_service``) are shared, not a robot's. Each runs in the embedded mode and again
across two server processes in scaled mode (the ``servers`` fixture's param).
"""
