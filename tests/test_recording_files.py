"""Recording files: ROS 1 schemas and messages that the ``mcap`` reader decodes, rotation,
and files cut short by a stop mid-file."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap_ros1.decoder import DecoderFactory

from telemetry.domain import ros1
from telemetry.recording import files

NS = 1_000_000_000
POSE = {
    "header": {"stamp": {"sec": 5, "nanosec": 7}, "frame_id": "b/Hall"},
    "pose": {"position": {"x": 1.5, "y": -2.0}, "orientation": {"z": 0.6, "w": 0.8}},
}
SCAN = {
    "header": {"stamp": {"secs": 5, "nsecs": 9}, "frame_id": "laser"},
    "angle_min": -1.0,
    "angle_max": 1.0,
    "angle_increment": 0.5,
    "range_min": 0.1,
    "range_max": 10.0,
    "ranges": [1.0, None, 2.5, 3.0, 4.0],
}


def record(topic: str, type_name: str, msg: dict, t: int) -> files.Record:
    schema = ros1.schema_text(type_name).encode()
    return files.Record(topic, type_name, schema, t, ros1.encode(type_name, msg))


def decoded(path: Path) -> list[tuple[str, str, int, Any]]:
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [
            (channel.topic, schema.name if schema else "", message.log_time, ros)
            for schema, channel, message, ros in reader.iter_decoded_messages()
        ]


def test_the_ros1_schema_is_the_full_definition_as_rosbag_writes_it():
    text = ros1.schema_text("geometry_msgs/PoseStamped")
    assert text.startswith("std_msgs/Header header\ngeometry_msgs/Pose pose\n")
    assert "=" * 80 + "\nMSG: geometry_msgs/Quaternion\n" in text
    assert ros1.md5sum("geometry_msgs/PoseStamped") == "d3812c3cbc69362b77dc0b19b345f8f5"


def test_a_written_file_reads_back_with_mcap_ros1_message_by_message(tmp_path):
    writer = files.RotatingFiles(tmp_path, "r1", max_seconds=3600, max_bytes=2**30)
    writer.write(record("/r1/pose", "geometry_msgs/PoseStamped", POSE, 10 * NS))
    writer.write(record("/r1/scan", "sensor_msgs/LaserScan", SCAN, 11 * NS))
    writer.close()
    [f] = files.files_of(tmp_path, "r1")
    assert files.finished(f.path)
    (t1, s1, l1, pose), (t2, s2, l2, scan) = decoded(f.path)
    assert (t1, s1, l1) == ("/r1/pose", "geometry_msgs/PoseStamped", 10 * NS)
    assert (pose.header.stamp.secs, pose.header.stamp.nsecs) == (5, 7)
    assert pose.header.frame_id == "b/Hall"
    assert (pose.pose.position.x, pose.pose.position.y, pose.pose.orientation.w) == (1.5, -2.0, 0.8)
    assert (t2, s2, l2) == ("/r1/scan", "sensor_msgs/LaserScan", 11 * NS)
    assert scan.header.stamp.nsecs == 9
    assert scan.ranges[0] == 1.0
    assert math.isnan(scan.ranges[1])
    assert scan.ranges[4] == 4.0


def test_files_rotate_by_time_and_by_size(tmp_path):
    writer = files.RotatingFiles(tmp_path, "r1", max_seconds=60, max_bytes=2**30)
    for second in (0, 30, 61, 200):
        writer.write(record("/r1/pose", "geometry_msgs/PoseStamped", POSE, (1000 + second) * NS))
    writer.close()
    assert [f.start_ns for f in files.files_of(tmp_path, "r1")] == [
        1000 * NS,
        1061 * NS,
        1200 * NS,
    ]
    small = files.RotatingFiles(tmp_path, "r2", max_seconds=3600, max_bytes=1)
    for i in range(3 * files.SIZE_EVERY):
        small.write(record("/r2/pose", "geometry_msgs/PoseStamped", POSE, (10 + i) * NS))
    small.close()
    # the size is looked at every SIZE_EVERY messages: no file passes it by more
    counts = [
        len(list(files.open_messages(f.path, 0, 2**62))) for f in files.files_of(tmp_path, "r2")
    ]
    assert len(counts) == 3
    assert max(counts) <= files.SIZE_EVERY
    assert sum(counts) == 3 * files.SIZE_EVERY


def test_a_file_cut_short_is_read_to_its_last_chunk_and_repaired(tmp_path):
    writer = files.RotatingFiles(tmp_path, "r1", max_seconds=3600, max_bytes=2**30)
    scan = {**SCAN, "ranges": [1.0] * 2000}
    for i in range(200):  # several chunks of 256 KiB
        writer.write(record("/r1/scan", "sensor_msgs/LaserScan", scan, (100 + i) * NS))
    path = writer.path
    assert path is not None
    assert writer._out is not None
    writer._out.flush()  # the process dies here: no summary, no footer
    cut = path.read_bytes()
    path.write_bytes(cut[: len(cut) - 100])  # and its last bytes are half written
    assert not files.finished(path)
    read = list(files.open_messages(path, 0, 2**63 - 1))
    assert 0 < len(read) < 200
    assert [r.log_time for r in read] == [(100 + i) * NS for i in range(len(read))]
    files.repair(path)
    assert files.finished(path)
    assert len(decoded(path)) == len(read)


def test_messages_between_two_times_come_from_the_files_that_may_hold_them(tmp_path):
    writer = files.RotatingFiles(tmp_path, "r1", max_seconds=10, max_bytes=2**30)
    for second in range(0, 40, 2):
        writer.write(record("/r1/pose", "geometry_msgs/PoseStamped", POSE, second * NS))
    writer.close()
    chosen = files.files_between(tmp_path, "r1", 15 * NS, 21 * NS)
    assert [f.start_ns // NS for f in chosen] == [10, 20]
    times = [
        r.log_time // NS for f in chosen for r in files.open_messages(f.path, 15 * NS, 21 * NS)
    ]
    assert times == [16, 18, 20]
    assert files.files_between(tmp_path, "nobody", 0, 10 * NS) == []
