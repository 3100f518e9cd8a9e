"""Fiducial marker dictionaries by OpenCV name (``DICT_APRILTAG_36h11`` and the like)."""

from __future__ import annotations

from functools import lru_cache

import cv2


@lru_cache(maxsize=16)
def marker_dictionary(name: str) -> cv2.aruco.Dictionary:
    """Return OpenCV's predefined dictionary ``name``; raises ValueError for an unknown name."""
    if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise ValueError(f"'{name}' is not an OpenCV marker dictionary.")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def marker_id_limit(name: str) -> int:
    """Return how many marker ids dictionary ``name`` holds (ids run from 0 to this minus one)."""
    return int(marker_dictionary(name).bytesList.shape[0])
