"""What a server refuses to start with outside the demo."""

from __future__ import annotations

from django.conf import settings
from django.core.exceptions import ImproperlyConfigured


def refuse_demo_secret_key() -> None:
    """Raise ImproperlyConfigured if the server would sign sessions with the public demo
    key while not running as the demo (``CLOUDNAV_DEMO``, which ``make demo`` sets)."""
    if settings.SECRET_KEY == settings.DEMO_SECRET_KEY and not settings.CLOUDNAV_DEMO:
        raise ImproperlyConfigured(
            "SECRET_KEY is the public demo key: set SECRET_KEY to a long random secret "
            "(README, Production), or run the demo with make demo."
        )
