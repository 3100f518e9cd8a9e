from __future__ import annotations

from django.apps import AppConfig


class RobotsConfig(AppConfig):
    name = "robots"
