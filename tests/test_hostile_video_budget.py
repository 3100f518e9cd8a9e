"""The video-encoder budget counts what an encoder really holds (issue 23 point 12): the
estimate of a VP8 pipeline is at least the resident memory one takes, measured in a
process of its own, and not wildly more."""

from __future__ import annotations

import subprocess
import sys

import pytest

from telemetry.domain.video import ImageParams, StreamParams, Vp8Params, encoder_memory
from tests.fixtures_live import BASE_DIR

# Encodes 12 frames of noise at WIDTH x HEIGHT through the pipeline's encoder; prints the
# growth of the process's resident memory (its peak), in bytes.
MEASURE = """
import sys, time
import cv2, numpy as np, psutil
from telemetry.domain.video import Frame, ImageParams, Vp8Params
from telemetry.domain.vp8 import Vp8Encoder

width, height = int(sys.argv[1]), int(sys.argv[2])
noise = np.random.default_rng(1).integers(0, 255, (height, width, 3), dtype=np.uint8)
jpegs = [cv2.imencode(".jpg", noise // (i + 1))[1].tobytes() for i in range(3)]
del noise
process = psutil.Process()
base = peak = process.memory_info().rss
encoder = Vp8Encoder(Vp8Params(), ImageParams(width=width, height=height))
for n in range(12):
    encoder.encode(Frame(jpegs[n % 3], "jpeg", None, time.time()), n * 100)
    peak = max(peak, process.memory_info().rss)
print(peak - base)
"""


def measured_encoder_memory(width: int, height: int) -> int:
    done = subprocess.run(
        [sys.executable, "-c", MEASURE, str(width), str(height)],
        cwd=BASE_DIR,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return int(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize(("width", "height"), [(640, 480), (1920, 1080)])
def test_a_vp8_encoders_estimate_covers_what_it_holds(width: int, height: int) -> None:
    params = StreamParams(
        type="vp8", image=ImageParams(width=width, height=height), vp8=Vp8Params()
    )
    estimate, measured = encoder_memory(params), measured_encoder_memory(width, height)
    assert measured <= estimate < 2 * measured, (measured, estimate)
