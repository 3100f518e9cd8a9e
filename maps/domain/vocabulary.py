"""A vocabulary of binary visual words for ORB descriptors: the global descriptor of a
keyframe is its bag of these words (``Vocabulary.bag``).

The words are trained once by k-majority (k-means for bit strings: nearest word by
Hamming distance, each word then the per-bit majority of its members) on ORB descriptors
of rendered views (``scripts/train_vocabulary.py``) and ship with the code as
``orb_vocabulary.npz``: ``words`` (k x 32 bytes) and ``idf`` (k inverse document
frequencies, ``log(frames / frames holding the word)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

VOCABULARY_FILE = Path(__file__).with_name("orb_vocabulary.npz")


@dataclass(frozen=True, eq=False)
class Vocabulary:
    words: NDArray[np.uint8]
    idf: NDArray[np.float32]

    @property
    def size(self) -> int:
        return int(self.words.shape[0])

    def assign(self, descriptors: NDArray[np.uint8]) -> NDArray[np.intp]:
        """The nearest word (Hamming) of each descriptor."""
        if descriptors.shape[0] == 0:
            return np.zeros(0, np.intp)
        matches = cv2.BFMatcher(cv2.NORM_HAMMING).match(descriptors, self.words)
        nearest = np.zeros(descriptors.shape[0], np.intp)
        for match in matches:
            nearest[match.queryIdx] = match.trainIdx
        return nearest

    def bag(self, descriptors: NDArray[np.uint8]) -> NDArray[np.float32]:
        """The tf-idf histogram of ``descriptors``' words, of unit length (zeros for none)."""
        counts = np.bincount(self.assign(descriptors), minlength=self.size).astype(np.float32)
        weighted = counts * self.idf
        norm = float(np.linalg.norm(weighted))
        return weighted / norm if norm > 0 else weighted

    def save(self, path: Path) -> None:
        np.savez_compressed(path, words=self.words, idf=self.idf)


@lru_cache(maxsize=1)
def default_vocabulary() -> Vocabulary:
    """The shipped vocabulary."""
    with np.load(VOCABULARY_FILE, allow_pickle=False) as stored:
        return Vocabulary(
            np.asarray(stored["words"], np.uint8), np.asarray(stored["idf"], np.float32)
        )


def train_vocabulary(
    frames: list[NDArray[np.uint8]], size: int, rounds: int = 12, seed: int = 0
) -> Vocabulary:
    """``size`` words by k-majority over the descriptors of ``frames`` (one array of
    n x 32 descriptors per frame), with the frames as documents for the idf."""
    rng = np.random.default_rng(seed)
    every = np.concatenate(frames)
    words = every[rng.choice(every.shape[0], size, replace=False)].copy()
    for _ in range(rounds):
        vocabulary = Vocabulary(words, np.ones(size, np.float32))
        nearest = vocabulary.assign(every)
        bits = np.unpackbits(every, axis=1).astype(np.float32)
        sums = np.zeros((size, bits.shape[1]), np.float32)
        np.add.at(sums, nearest, bits)
        members = np.bincount(nearest, minlength=size)
        filled = members > 0
        majority = sums[filled] >= members[filled, None] / 2
        words[filled] = np.packbits(majority, axis=1)
        empty = np.flatnonzero(~filled)  # reseed words nobody chose
        words[empty] = every[rng.choice(every.shape[0], empty.size, replace=False)]
    vocabulary = Vocabulary(words, np.ones(size, np.float32))
    holding = np.zeros(size, np.float32)
    for frame in frames:
        holding[np.unique(vocabulary.assign(frame))] += 1
    idf = np.log(len(frames) / np.maximum(holding, 1.0)).astype(np.float32)
    return Vocabulary(words, idf)
