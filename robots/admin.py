from __future__ import annotations

from django.contrib import admin

from .models import Robot, RobotState


@admin.register(Robot)
class RobotAdmin(admin.ModelAdmin[Robot]):
    list_display = ["name", "description", "created", "token_rotated"]
    filter_horizontal = ["buildings"]
    readonly_fields = ["token_rotated", "created"]


@admin.register(RobotState)
class RobotStateAdmin(admin.ModelAdmin[RobotState]):
    list_display = ["robot", "online", "map_id", "last_seen"]
