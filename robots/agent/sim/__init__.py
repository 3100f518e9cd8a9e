"""The simulated robot: ground truth (``world``), a differential-drive base (``body``), a
2D laser (``laser``) and a pinhole camera (``camera``), each writing its ROS messages with
the shared builders of ``cloudnav_core.messages``.

One ``World`` serves every sensor and many robots; each robot owns a ``DiffDriveBody``,
a ``Laser`` and a ``Camera``, each seeded, so a run is reproducible. Nothing here reads a
map the robot has downloaded: the sensors see ground truth, the detector sees pixels.
"""
