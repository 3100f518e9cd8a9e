"""Video relays of robot cameras, compatible with web_video_server.

Robots publish JPEG ``sensor_msgs/CompressedImage`` over rosbridge; this package takes
those frames off the topic bus (``feeds``), turns them into what viewers asked for, once
per topic and parameter set (``pipelines``, managed by ``relay``), and streams them over
HTTP (``streams``, ``views``) at the pace each viewer reads (``readiness``). Who may
watch which camera is decided in ``cameras``.
"""
