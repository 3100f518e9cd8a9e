"""The robot's side of the cloud's visual map: keyframes out while its pose is good, and
"where am I?" when it has none.

Keyframes: while the robot is localised in a sub-map and its pose is trustworthy (its
filter's spread within ``TRUSTED_SPREAD``, or no filter: odometry since a tag reset),
every frame taken with depth that stands ``KEYFRAME_DISTANCE`` or ``KEYFRAME_TURN`` away
from the last keyframe sent in that sub-map goes to the cloud
(``POST /api/buildings/{b}/maps/{m}/keyframes``: JPEG, depth as ROS's
``compressedDepth`` PNG, pose). One request
is in flight at a time; a frame that finds one under way is skipped, and so is a
keyframe the server refuses (a full queue answers 503: the next one will do).

Wake-up: ``ask`` sends one JPEG to ``POST /api/relocalise`` and reads the answer
(``/cloudnav/relocalise``'s fields). The robot asks when it has no sub-map and no marker
in sight, and when its filter's spread grows past ``LOST_SPREAD``, at most every
``ASK_INTERVAL`` seconds; a lost robot searching for a goal turns on the spot meanwhile,
so each question shows another view.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import httpx
import numpy as np
from numpy.typing import NDArray

from cloudnav_core.camera import CameraModel
from cloudnav_core.messages import camera_info, compressed_depth, compressed_image
from cloudnav_core.se2 import Pose
from robots.agent.hardware import encode_jpeg
from robots.agent.perception import pinhole_calibration
from robots.agent.relocalise import PoseEstimate

logger = logging.getLogger(__name__)

KEYFRAME_DISTANCE = 0.3
"""Metres between keyframes sent."""
KEYFRAME_TURN = math.radians(15.0)
"""...or radians of turn."""
TRUSTED_SPREAD = 0.15
"""Metres: a filter's position standard deviation within which keyframes are sent."""
LOST_SPREAD = 0.6
"""Metres: past this the robot counts itself lost and asks the cloud."""
ASK_INTERVAL = 2.0
"""Simulated seconds between questions."""
JPEG_QUALITY = 90


@dataclass(frozen=True)
class Placement:
    """A localised answer: the Map ID and the pose estimate in it."""

    map_id: str
    estimate: PoseEstimate
    inliers: int


class VisualMap:
    """Keyframes and questions over ``http`` (a client with the robot's token)."""

    def __init__(self, http: httpx.AsyncClient, model: CameraModel) -> None:
        self.http = http
        self.model = model
        self.sent = 0
        self.refused = 0
        self.asked = 0
        self.busy = False
        self._last_keyframe: dict[str, Pose] = {}
        self._last_ask = -math.inf

    # --- keyframes -------------------------------------------------------------------------

    def keyframe_due(self, map_id: str, pose: Pose) -> bool:
        """Whether a keyframe at ``pose`` in ``map_id`` is far enough from the last one."""
        if self.busy:
            return False
        last = self._last_keyframe.get(map_id)
        if last is None:
            return True
        moved = math.hypot(pose[0] - last[0], pose[1] - last[1])
        turned = abs(math.remainder(pose[2] - last[2], math.tau))
        return moved >= KEYFRAME_DISTANCE or turned >= KEYFRAME_TURN

    async def send_keyframe(
        self, map_id: str, pose: Pose, image: NDArray[np.uint8], depth: NDArray[np.float32]
    ) -> None:
        """Send one keyframe; failures are logged, never raised."""
        self.busy = True
        self._last_keyframe[map_id] = pose
        building, _, code = map_id.partition("/")
        body = keyframe_document(self.model, pose, image, depth)
        try:
            response = await self.http.post(
                f"/api/buildings/{building}/maps/{code}/keyframes", json=body
            )
            if response.status_code == 202:
                self.sent += 1
            else:
                self.refused += 1
                logger.info(
                    "keyframe refused: HTTP %s %s", response.status_code, response.text[:200]
                )
        except httpx.HTTPError as error:
            logger.warning("keyframe not sent: %r", error)
        finally:
            self.busy = False

    # --- questions -------------------------------------------------------------------------

    def may_ask(self, seconds: float) -> bool:
        return not self.busy and seconds - self._last_ask >= ASK_INTERVAL

    async def ask(
        self, image: NDArray[np.uint8], seconds: float, building: str = ""
    ) -> Placement | None:
        """Where ``image`` was taken, by the cloud; None when it cannot say (the reason
        is logged) or cannot be reached."""
        self.busy = True
        self._last_ask = seconds
        self.asked += 1
        body: dict[str, Any] = {
            "images": [compressed_image("camera", encode_jpeg(image, JPEG_QUALITY), 0.0)],
            "camera_info": camera_info_of(self.model),
            "mount": mount_of(self.model),
        }
        if building:
            body["building"] = building
        try:
            response = await self.http.post("/api/relocalise", json=body, timeout=30.0)
        except httpx.HTTPError as error:
            logger.warning("relocalisation not asked: %r", error)
            return None
        finally:
            self.busy = False
        return _placement(response)


def keyframe_document(
    model: CameraModel, pose: Pose, image: NDArray[np.uint8], depth: NDArray[np.float32]
) -> dict[str, Any]:
    """The body of a keyframe request: the image as JPEG, the depth as ROS's
    ``compressedDepth`` (a 16-bit PNG: a few kB where the raw ``sensor_msgs/Image`` is
    about 800 kB of JSON), the camera and the pose."""
    return {
        "image": compressed_image("camera", encode_jpeg(image, JPEG_QUALITY), 0.0),
        "depth": compressed_depth("camera", depth, 0.0),
        "camera_info": camera_info_of(model),
        "mount": mount_of(model),
        "pose": {"x": pose[0], "y": pose[1], "yaw": pose[2]},
    }


def camera_info_of(model: CameraModel) -> Any:
    return camera_info("camera", pinhole_calibration(model), 0.0)


def mount_of(model: CameraModel) -> dict[str, float]:
    return {"forward": model.mount_x, "height": model.mount_height}


def _placement(response: httpx.Response) -> Placement | None:
    if response.status_code != 200:
        logger.warning(
            "relocalisation refused: HTTP %s %s", response.status_code, response.text[:200]
        )
        return None
    answer = response.json()
    if not answer.get("localised"):
        logger.info("not localised by the cloud: %s", answer.get("reason"))
        return None
    try:
        pose = answer["pose"]
        covariance = np.array(answer["covariance"], np.float64).reshape(3, 3)
        estimate = PoseEstimate(float(pose["x"]), float(pose["y"]), float(pose["yaw"]), covariance)
        return Placement(str(answer["map_id"]), estimate, int(answer["inliers"]))
    except (KeyError, TypeError, ValueError) as error:
        logger.warning("a relocalisation answer that cannot be read: %r", error)
        return None


def spread(covariance: NDArray[np.float64]) -> float:
    """Metres: the position standard deviation of a 3x3 (x, y, yaw) covariance."""
    return math.sqrt(max(float(covariance[0, 0] + covariance[1, 1]), 0.0))
