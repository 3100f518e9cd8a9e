"""ASGI entry point: HTTP through Django, WebSockets (rosbridge) through Channels.

Browsers authenticate with their Django session (``AuthMiddlewareStack``); the rosbridge
consumer checks their origin and robot tokens itself. Outside the demo, the server refuses
to start with the public default ``SECRET_KEY``. ``TransportProbe`` sits outermost so
the consumer can reach daphne's own ``send`` (see ``telemetry.transport``). Under daphne,
``bodies.install`` refuses request bodies that are too large, or come without credentials
that hold, before daphne keeps them, and ``headers.install`` closes connections whose
headers do not arrive in time; ``access_log.install`` sends daphne's access log through
logging (unchanged checks at DEBUG); ``redaction.install`` keeps robot tokens out of it;
``shutdown.install`` makes SIGTERM finish every task and thread
before the process exits.
"""

from __future__ import annotations

import os

from django.core.asgi import get_asgi_application

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "cloudnav_web.settings")
django_asgi_app = get_asgi_application()

from channels.auth import AuthMiddlewareStack  # noqa: E402
from channels.routing import ProtocolTypeRouter, URLRouter  # noqa: E402

from cloudnav_web import access_log, bodies, deployment, headers, redaction, shutdown  # noqa: E402
from telemetry.routing import websocket_urlpatterns  # noqa: E402
from telemetry.transport import TransportProbe  # noqa: E402

deployment.refuse_demo_secret_key()
bodies.install()
headers.install()
access_log.install()  # before redaction: redaction wraps it, so what it logs is redacted
redaction.install()
shutdown.install()
application = ProtocolTypeRouter(
    {
        "http": django_asgi_app,
        "websocket": TransportProbe(AuthMiddlewareStack(URLRouter(websocket_urlpatterns))),
    }
)
