"""ASGI entry point: HTTP through Django, WebSockets (rosbridge) through Channels.

Browsers authenticate with their Django session (``AuthMiddlewareStack``); the rosbridge
consumer checks their origin and robot tokens itself. Outside the demo, the server refuses
to start with the public default ``SECRET_KEY``. ``TransportProbe`` sits outermost so
the consumer can reach daphne's own ``send`` (see ``telemetry.rosbridge.transport``). Under daphne,
``bodies.install`` refuses request bodies that are too large, or come without credentials
that hold, before daphne keeps them, and ``headers.install`` closes connections whose
headers do not arrive in time; ``access_log.install`` sends daphne's access log through
logging (unchanged checks at DEBUG); ``redaction.install`` keeps robot tokens out of it;
``background.install`` starts the workers that serve requests and has each hub start
those that tap it (the one place the server's workers start); ``shutdown.install`` makes
SIGTERM finish every task and stop and join every worker before the process exits.

Last, everything loaded so far (modules, settings, URL patterns: about 170,000 objects,
alive as long as the process) is moved out of the garbage collector's reach
(``gc.freeze``): each collection of the oldest generation walked all of them in the
middle of the relay's traffic, 0.7 to 1.2 s each on the 2-core machine at load 11.
"""

from __future__ import annotations

import gc
import os

from django.core.asgi import get_asgi_application

os.environ.setdefault("DJANGO_SETTINGS_MODULE", "cloudnav_web.settings")
django_asgi_app = get_asgi_application()

from channels.auth import AuthMiddlewareStack  # noqa: E402
from channels.routing import ProtocolTypeRouter, URLRouter  # noqa: E402

from cloudnav_web import (  # noqa: E402
    access_log,
    background,
    bodies,
    deployment,
    headers,
    redaction,
    shutdown,
)
from telemetry.rosbridge.routing import websocket_urlpatterns  # noqa: E402
from telemetry.rosbridge.transport import TransportProbe  # noqa: E402

deployment.refuse_demo_secret_key()
bodies.install()
headers.install()
access_log.install()  # before redaction: redaction wraps it, so what it logs is redacted
redaction.install()
shutdown.install()
background.install()
application = ProtocolTypeRouter(
    {
        "http": django_asgi_app,
        "websocket": TransportProbe(AuthMiddlewareStack(URLRouter(websocket_urlpatterns))),
    }
)
gc.freeze()
