"""Recordings survive retention and a crash, across processes: a file is being written
while its writer (in any process) holds its lock, so retention and repair leave it alone,
and a file whose writer died is repaired by the next recorder to start (real processes,
real files, real locks)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from telemetry.domain import ros1
from telemetry.recording import files
from telemetry.recording.plans import DEFAULT, Retention
from telemetry.recording.recorder import Recorder, RecorderConfig, prune
from tests.fixtures_live import BASE_DIR

NS = 1_000_000_000

# A server process's recorder, reduced to its files: it writes a chunk of poses to robot
# argv[2]'s file under argv[1], says which file, and keeps writing until told to stop.
WRITER = """
import sys
from pathlib import Path
from telemetry.domain import ros1
from telemetry.recording import files
pose = {"header": {"frame_id": "b/Hall"}, "pose": {"position": {"x": 1.0}}}
kind = "geometry_msgs/PoseStamped"
schema = ros1.schema_text(kind).encode()
writer = files.RotatingFiles(Path(sys.argv[1]), sys.argv[2], 3600, 2**30)
for i in range(50):
    writer.write(files.Record("/" + sys.argv[2] + "/pose", kind, schema, (10**9 + i) * 10**9,
                              ros1.encode(kind, pose)))
writer.flush()
print(writer.path, flush=True)
sys.stdin.readline()
writer.close()
"""


@contextmanager
def writing_process(root: Path, robot: str) -> Iterator[tuple[subprocess.Popen[str], Path]]:
    """Another process writing ``robot``'s recording under ``root``: yields it and its file."""
    process = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(root), robot],
        cwd=BASE_DIR,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        path = Path(process.stdout.readline().strip())
        assert path.is_file(), "the writing process did not start"
        yield process, path
    finally:
        if process.poll() is None:
            process.kill()
        process.wait(10)


def note(robot: str, t_ns: int) -> files.Record:
    kind = "std_msgs/String"
    data = ros1.encode(kind, {"data": "note"})
    return files.Record(f"/{robot}/note", kind, ros1.schema_text(kind).encode(), t_ns, data)


def closed_file(root: Path, robot: str, start_s: int) -> Path:
    """A finished recording of ``robot`` starting at ``start_s``, closed by its writer."""
    writer = files.RotatingFiles(root, robot, 3600, 2**30)
    writer.write(note(robot, start_s * NS))
    path = writer.path
    writer.close()
    assert path is not None
    assert files.finished(path)
    return path


def test_retention_never_deletes_a_file_another_process_is_writing(tmp_path):
    old = closed_file(tmp_path, "r1", int(time.time()) - 7200)
    with writing_process(tmp_path, "r1") as (_process, theirs):
        nothing_kept = Retention("b", frozenset({"r1"}), days=7, budget=0)
        gone = prune(tmp_path, nothing_kept, time.time())
        assert gone == [old]
        assert theirs.exists()
        assert len(list(files.open_messages(theirs, 0, 2**63 - 1))) == 50


def test_retention_never_deletes_a_file_this_process_is_writing(tmp_path):
    writer = files.RotatingFiles(tmp_path, "r1", 3600, 2**30)
    ours = closed_file(tmp_path, "r1", int(time.time()))
    # the open file of this process's own writer
    writer.write(note("r1", time.time_ns()))
    writer.flush()
    prune(tmp_path, Retention("b", frozenset({"r1"}), days=7, budget=0), time.time())
    assert writer.path is not None
    assert writer.path.exists()
    assert not ours.exists()
    writer.close()


def start_recorder(root: Path) -> Recorder:
    recorder = Recorder(
        RecorderConfig(root=root), lambda robots: dict.fromkeys(robots, DEFAULT), lambda: []
    )
    recorder.start()
    return recorder


def test_a_recorder_repairs_at_start_what_a_killed_process_left_and_not_what_one_writes(
    tmp_path,
):
    with (
        writing_process(tmp_path, "r1") as (killed, left),
        writing_process(tmp_path, "r2") as (_alive, theirs),
    ):
        os.kill(killed.pid, signal.SIGKILL)
        killed.wait(10)
        assert not files.finished(left)
        size_before = theirs.stat().st_size
        recorder = start_recorder(tmp_path)
        try:
            deadline = time.monotonic() + 20
            while not files.finished(left):
                assert time.monotonic() < deadline, "the dead process's file was not repaired"
                time.sleep(0.05)
        finally:
            recorder.stop()
        assert len(list(files.open_messages(left, 0, 2**63 - 1))) == 50  # by its index now
        assert not files.finished(theirs)
        assert theirs.stat().st_size == size_before
