"""Admins choose what each building records and keeps."""

from __future__ import annotations

from django.contrib import admin

from .models import RecordingSettings


@admin.register(RecordingSettings)
class RecordingSettingsAdmin(admin.ModelAdmin[RecordingSettings]):
    list_display = ["building", "enabled", "topics", "camera_rate", "retention_days", "budget_mb"]
