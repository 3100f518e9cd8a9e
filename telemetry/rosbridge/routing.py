"""WebSocket routes: the rosbridge endpoint at ``/rosbridge`` and at ``/``.

Unmodified clients connect to the bare address (``roslibpy.Ros(host, port)``,
``new ROSLIB.Ros({url: 'ws://host:port'})``), hence ``/`` too.
"""

from __future__ import annotations

from django.urls import re_path

from .consumers import RosbridgeConsumer

websocket_urlpatterns = [
    re_path(r"^(rosbridge/?)?$", RosbridgeConsumer.as_asgi()),
]
