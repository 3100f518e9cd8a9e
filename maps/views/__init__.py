"""REST adapters of the map store: parse, authorise, call one service, answer.

The modules, one resource each: ``lookups`` (the building, sub-map or tag a request
names, if the caller may), ``buildings``, ``members``, ``submaps``, ``map_files`` (a map
file's image and grid as responses, for sub-maps and their versions), ``map_versions``,
``visual_map`` (keyframes and visual relocalisation), ``topology`` (the graph, its
validation and routes), ``tags`` and ``parking``.
"""
