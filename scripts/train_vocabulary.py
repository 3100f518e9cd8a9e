"""Train the ORB vocabulary the server ships (maps/domain/orb_vocabulary.npz).

Views of a building no benchmark or test uses (the demo floor plan under the code
``vocabulary_0``, seed 9001) from poses spread over its free space: the words learn
what rendered walls look like, not the places the benchmarks visit.

Run: ``.venv/bin/python scripts/train_vocabulary.py`` (about a minute on two cores).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from maps.domain.keyframes import FeatureExtractor
from maps.domain.vocabulary import VOCABULARY_FILE, Vocabulary, train_vocabulary
from robots.agent.sim.camera import Camera
from robots.agent.sim.world import demo_world

WORDS = 1024
VIEWS = 400


def main() -> None:
    world = demo_world(seed=9001, building_code="vocabulary_0")
    camera = Camera(world, seed=9001)
    extractor = FeatureExtractor(Vocabulary(np.zeros((1, 32), np.uint8), np.ones(1, np.float32)))
    rng = np.random.default_rng(9001)
    frames: list[np.ndarray] = []
    while len(frames) < VIEWS:
        x = rng.uniform(0, world.cells.shape[1] * world.resolution) + world.origin[0]
        y = rng.uniform(0, world.cells.shape[0] * world.resolution) + world.origin[1]
        if not world.disc_is_free(x, y, 0.3):
            continue
        _, descriptors = extractor.detect(camera.render((x, y, rng.uniform(-math.pi, math.pi))))
        if descriptors.shape[0] >= 50:
            frames.append(descriptors)
    train_vocabulary(frames, WORDS).save(VOCABULARY_FILE)
    print(f"{WORDS} words from {sum(f.shape[0] for f in frames)} descriptors of {VIEWS} views")


if __name__ == "__main__":
    main()
