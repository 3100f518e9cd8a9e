"""HTTP routes of telemetry: video relays and statistics, recordings (added as they are built)."""

from __future__ import annotations

from django.urls import URLPattern, path

from telemetry import event_views as events
from telemetry.recording import settings_views as recording_settings
from telemetry.recording import views as recording
from telemetry.video import views as video

urlpatterns: list[URLPattern] = [
    # web_video_server's URLs, without a trailing slash as there
    path("stream", video.stream, name="video-stream"),
    path("snapshot", video.snapshot_view, name="video-snapshot"),
    path("stream_viewer", video.stream_viewer, name="video-viewer"),
    # WebRTC by WHEP: POST an SDP offer, DELETE the Location answered
    path("whep", video.whep, name="video-whep"),
    path("whep/<str:session>", video.whep_session, name="video-whep-session"),
    path("video/", video.camera_topics, name="video-page"),
    path("api/video/stats", video.video_stats, name="video-stats"),
    path("api/events/", events.EventList.as_view(), name="events"),
    path("api/events/<int:pk>/acknowledge", events.Acknowledge.as_view(), name="event-ack"),
    path("api/alerts/open", events.OpenAlerts.as_view(), name="alerts-open"),
    path(
        "api/robots/<slug:name>/recording.mcap",
        recording.RobotRecording.as_view(),
        name="robot-recording",
    ),
    path(
        "api/buildings/<slug:code>/recording.mcap",
        recording.BuildingRecording.as_view(),
        name="building-recording",
    ),
    path(
        "api/buildings/<slug:code>/recording/",
        recording_settings.BuildingRecordingSettings.as_view(),
        name="building-recording-settings",
    ),
    path(
        "api/robots/<slug:name>/recording.json",
        recording.RobotReplay.as_view(),
        name="robot-replay",
    ),
    path(
        "api/robots/<slug:name>/recording.bag",
        recording.RobotRecording.as_view(kind="bag"),
        name="robot-recording-bag",
    ),
    path(
        "api/buildings/<slug:code>/recording.bag",
        recording.BuildingRecording.as_view(kind="bag"),
        name="building-recording-bag",
    ),
]
