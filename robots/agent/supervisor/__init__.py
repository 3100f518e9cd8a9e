"""The Maps Supervisor: which sub-map the robot is in, the bundles it holds, and what to
drive to next on the way to a goal in another sub-map.

The modules, one concern each:

- ``submaps``: ``SubMap`` (one decoded bundle: grid, frame, tags, topology) and
  ``StoredTag``, read from a bundle by ``submap_from_bundle``;
- ``bundle_cache``: ``BundleCache``, the bundles fetched over HTTP and kept by Map ID;
- ``legs``: what the supervisor tells the driver (``Leg``, ``LegKind``) and the goal it
  works toward (``Destination``);
- ``maps_supervisor``: ``MapsSupervisor``, the paper's procedure tick by tick.
"""
