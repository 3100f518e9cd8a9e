"""The recorder: what it takes from the bus, what it drops under a flood, what it keeps."""

from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path

from telemetry.domain import ros1
from telemetry.domain.bus import Topic
from telemetry.domain.events import EventDraft, Kind, Severity
from telemetry.recording import files
from telemetry.recording.plans import DEFAULT, NOTHING, Plan, Retention
from telemetry.recording.recorder import Recorder, RecorderConfig, prune

POSE = {"header": {"frame_id": "b/Hall"}, "pose": {"position": {"x": 1.0}}}
POSE_TOPIC = Topic("/r1/pose", "geometry_msgs/PoseStamped")


def make_recorder(root: Path, plan: Plan = DEFAULT, **kwargs) -> Recorder:
    kwargs.setdefault("queue_size", 100)
    clock = kwargs.pop("clock", time.time)
    return Recorder(
        RecorderConfig(root=root, **kwargs),
        lambda robots: dict.fromkeys(robots, plan),
        lambda: [],
        clock,
    )


def recorded(root: Path, robot: str = "r1") -> list[files.Record]:
    return [r for f in files.files_of(root, robot) for r in files.open_messages(f.path, 0, 2**62)]


def test_it_records_only_the_robots_connected_here(tmp_path):
    recorder = make_recorder(tmp_path)
    recorder.offered(POSE_TOPIC, POSE)
    recorder.connected("r1")
    recorder.offered(POSE_TOPIC, POSE)
    recorder.offered(Topic("/r2/pose", "geometry_msgs/PoseStamped"), POSE)
    recorder.step()
    recorder.disconnected("r1")
    recorder.step()
    assert [r.topic for r in recorded(tmp_path)] == ["/r1/pose"]
    assert files.files_of(tmp_path, "r2") == []


def test_it_counts_what_a_flood_makes_it_drop_and_never_holds_more_than_its_queue(tmp_path):
    recorder = make_recorder(tmp_path, queue_size=50)
    recorder.connected("r1")
    for _ in range(1000):
        recorder.offered(POSE_TOPIC, POSE)
    assert recorder.stats()["r1"] == {"queued": 50, "dropped": 950, "written": 0}
    recorder.step()
    assert recorder.stats()["r1"] == {"queued": 0, "dropped": 950, "written": 50}
    recorder.disconnected("r1")
    recorder.step()
    assert len(recorded(tmp_path)) == 50


def test_robots_that_arrive_have_their_plans_read_and_the_others_wait_for_the_round(tmp_path):
    asked: list[list[str]] = []

    def plans(robots: list[str]) -> dict[str, Plan]:
        asked.append(sorted(robots))
        return dict.fromkeys(robots, DEFAULT)

    recorder = Recorder(RecorderConfig(root=tmp_path), plans, lambda: [])
    for robot in ("r1", "r2", "r3"):
        recorder.connected(robot)
        recorder.step()
    recorder.step()  # all planned: nothing asked until the next round
    assert asked == [["r1"], ["r2"], ["r3"]]  # not everyone again for each arrival


def test_the_plan_chooses_the_topics_and_the_camera_rate(tmp_path):
    now = [1000.0]
    plan = Plan(frozenset({"pose", "camera/image/compressed"}), camera_interval=0.5)
    recorder = make_recorder(tmp_path, plan, clock=lambda: now[0])
    recorder.connected("r1")
    recorder.step()  # the plan is read
    camera = Topic("/r1/camera/image/compressed", "sensor_msgs/CompressedImage")
    frame = {"format": "jpeg", "data": "AAEC"}
    for _ in range(10):  # 10 frames at 10 Hz: one every 0.5 s is kept
        recorder.offered(camera, frame)
        recorder.offered(Topic("/r1/odom", "nav_msgs/Odometry"), {})
        now[0] += 0.1
    recorder.disconnected("r1")
    recorder.step()
    kept = recorded(tmp_path)
    assert [r.topic for r in kept] == ["/r1/camera/image/compressed"] * 2
    assert kept[0].data.endswith(b"\x03\x00\x00\x00\x00\x01\x02")


def test_a_message_that_is_not_its_type_is_counted_and_skipped(tmp_path):
    recorder = make_recorder(tmp_path)
    recorder.connected("r1")
    recorder.offered(POSE_TOPIC, {"pose": "not a pose"})
    recorder.offered(POSE_TOPIC, POSE)
    recorder.step()
    assert recorder.robots["r1"].failed == 1
    assert recorder.robots["r1"].written == 1


def test_a_full_disk_costs_a_message_and_the_oldest_file_never_the_recorder(tmp_path, monkeypatch):
    now = [1000.0]
    recorder = make_recorder(tmp_path, file_seconds=1, clock=lambda: now[0])
    recorder.connected("r1")
    for _ in range(3):
        recorder.offered(POSE_TOPIC, POSE)
        recorder.step()
        now[0] += 2
    oldest, *others = files.files_of(tmp_path, "r1")
    assert len(others) == 2
    real_write = files.RotatingFiles.write

    def full(self, record):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(files.RotatingFiles, "write", full)
    recorder.offered(POSE_TOPIC, POSE)
    recorder.step()
    monkeypatch.setattr(files.RotatingFiles, "write", real_write)
    assert recorder.robots["r1"].dropped == 1
    assert not oldest.path.exists()
    recorder.offered(POSE_TOPIC, POSE)
    recorder.step()
    assert recorder.robots["r1"].written == 4


def write_file(root: Path, robot: str, start_s: int, size: int, age_s: float) -> Path:
    directory = root / robot
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{start_s * 10**9}-test.mcap"
    path.write_bytes(b"x" * size)
    then = time.time() - age_s
    os.utime(path, (then, then))
    return path


def test_retention_deletes_files_past_their_days_then_the_oldest_past_the_budget(tmp_path):
    now = time.time()
    ancient = write_file(tmp_path, "r1", int(now - 10 * 86400), 100, 9 * 86400)
    old = write_file(tmp_path, "r1", int(now - 3 * 86400), 400, 2 * 86400)
    older_r2 = write_file(tmp_path, "r2", int(now - 4 * 86400), 400, 3 * 86400)
    new = write_file(tmp_path, "r2", int(now - 3600), 400, 60)
    writing = write_file(tmp_path, "r1", int(now - 60), 400, 1)
    kept_elsewhere = write_file(tmp_path, "r9", int(now - 10 * 86400), 100, 9 * 86400)
    retention = Retention("b", frozenset({"r1", "r2"}), days=7, budget=900)
    with open(writing, "rb") as held:  # as its writer holds it
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)
        gone = prune(tmp_path, retention, now)
    assert gone == [ancient, older_r2, old]
    assert new.exists()
    assert writing.exists()
    assert kept_elsewhere.exists()


def lapsed(robot: str, at: float) -> EventDraft:
    return EventDraft(
        at, Kind.TELEOP_LAPSED, Severity.WARNING, robot, "lock lapsed", actor="user:ann"
    )


def test_events_go_on_the_robots_events_channel_at_their_time_through_its_queue(tmp_path):
    recorder = make_recorder(tmp_path, queue_size=2)
    recorder.event(lapsed("r1", 1000.5))  # not connected here: another process records it
    recorder.connected("r1")
    recorder.event(lapsed("r1", 1000.5))
    recorder.offered(POSE_TOPIC, POSE)
    recorder.event(lapsed("r1", 1001.0))  # the queue is full: counted, the relay never waits
    assert recorder.stats()["r1"] == {"queued": 2, "dropped": 1, "written": 0}
    recorder.step()
    recorder.disconnected("r1")
    recorder.step()
    [event, _pose] = recorded(tmp_path)
    assert (event.topic, event.type_name, event.log_time) == (
        "/r1/events",
        "rosgraph_msgs/Log",
        1_000_500_000_000,
    )
    log = ros1.decode(event.type_name, event.data)
    assert (log.level, log.name, log.msg) == (4, "teleop_lapsed", "lock lapsed")
    assert "actor=user:ann" in list(log.topics)


def test_a_robot_recording_nothing_records_no_event(tmp_path):
    recorder = make_recorder(tmp_path, NOTHING)
    recorder.connected("r1")
    recorder.event(lapsed("r1", 1000.0))  # before its plan is read: dropped when written
    recorder.step()
    recorder.event(lapsed("r1", 1001.0))
    recorder.disconnected("r1")
    recorder.step()
    assert recorded(tmp_path) == []
