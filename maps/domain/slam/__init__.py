"""2D SLAM from a robot's laser scans and odometry: correlative scan matching against the
map being built, occupancy by log-odds, and a pose graph with loop closure.

Every scan comes with the odometry pose of its instant. The odometry step since the last
scan predicts the pose; the scan is matched against the map near the robot
(``matching``). A scan taken after the robot moved ``keyframe_distance`` or turned
``keyframe_angle`` becomes a keyframe: a node of the pose graph, tied to the previous
keyframe by the matched relative pose; a new keyframe near an old one may close a loop,
and the graph is then optimised (``pose_graph``). The occupancy grid adds each keyframe's
scan once (``occupancy``).

The modules, one concern each:

- ``params``: ``SlamParams``, the mapper's tuning;
- ``scans``: ``Scan`` (a laser scan as SLAM uses it, read from its message) and
  ``Keyframe`` (a scan with its map-frame pose);
- ``matching``: the likelihood field and the correlative search over poses;
- ``pose_graph``: the pose graph's optimisation (GTSAM);
- ``occupancy``: the log-odds occupancy grid;
- ``mapper``: ``Mapper``, which builds one map from a stream of scans, with its
  ``MapStats`` and its saved state.

Nothing here imports Django: the server runs it in a worker thread, tests and benchmarks
on simulated tours.
"""
