"""What the adapters call: accept a keyframe, relocalise a robot.

Both take the request document as it arrived (rosbridge JSON or a REST body: the same
fields) and raise KeyframeError (a 400, or a failed service call) for anything unusable,
before anything is queued or searched; ``KeyframeQueueFull`` when the ingestion queue
is full. Who may ask is the caller's business (the adapters know who it is):
``buildings_to_search`` turns the buildings a caller may relocalise in into the ones a
request searches, and ``relocalise_queued`` answers on the relocalisation lanes
(``maps.visual.lanes``), which both adapters share.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from concurrent.futures import Future
from typing import Any

from django.conf import settings
from django.db import close_old_connections

from cloudnav_core.camera import Mount
from maps.domain.keyframes import FeatureExtractor
from maps.domain.relocalisation import Answer, QueryFrame, relocalise
from maps.domain.visual_input import (
    depth_image,
    grey_image,
    image_list,
    intrinsics_of,
    planar_pose,
)
from maps.domain.vocabulary import default_vocabulary
from maps.exceptions import KeyframeError, RelocalisationRefused
from maps.models import Building, SubMap
from maps.visual import store
from maps.visual.lanes import Caller, relocalisation_lanes
from maps.visual.worker import Job, ingest_queue


class KeyframeQueueFull(Exception):
    """The ingestion queue is full: try again later."""


def mount_of(value: Any) -> Mount:
    """The camera's place on the robot, ``{forward, height}`` (the default robot's when
    absent)."""
    if value is None:
        return Mount()
    try:
        mount = Mount(float(value["forward"]), float(value["height"]))
    except (KeyError, TypeError, ValueError):
        raise KeyframeError("mount", "{forward, height} in metres is required") from None
    if not (abs(mount.forward) < 3 and 0 < mount.height < 3):  # NaN fails both
        raise KeyframeError("mount", "forward must be within (-3, 3) m and height within (0, 3) m")
    return mount


def accept_keyframe(submap: SubMap, robot: str, document: Mapping[str, Any]) -> None:
    """Check ``document`` (``image``, ``depth``, ``pose``, optional ``camera_info`` and
    ``mount``) and queue it as a keyframe of ``submap``."""
    limit = settings.CLOUDNAV_MAX_IMAGE_PIXELS
    image = grey_image(document.get("image"), limit)
    depth = depth_image(document.get("depth"), image.shape, limit)
    intrinsics = intrinsics_of(document.get("camera_info"), image.shape)
    pose = planar_pose(document.get("pose"))
    mount = mount_of(document.get("mount"))
    store.check_pose(submap, pose)
    job = Job(submap.pk, robot, image, depth, pose, intrinsics, mount)
    if not ingest_queue().submit(job):
        raise KeyframeQueueFull("the keyframe queue is full; send a later keyframe")


def buildings_to_search(allowed: Iterable[int], code: str | None) -> list[Building]:
    """The buildings a relocalisation request searches: among ``allowed`` (the pks of the
    buildings the caller may relocalise in), the one named ``code``, or all of them.
    Raises RelocalisationRefused when that is none (the same whether or not a building
    ``code`` exists)."""
    buildings = list(Building.objects.filter(pk__in=set(allowed)).order_by("code"))
    if code:
        buildings = [b for b in buildings if b.code == code]
        if not buildings:
            raise RelocalisationRefused(
                f"You may not relocalise in {code}: its robots and the people who may "
                "drive there may."
            )
    if not buildings:
        raise RelocalisationRefused(
            "You may relocalise in no building: a building's robots and the people who "
            "may drive there may."
        )
    return buildings


def relocalise_queued(
    caller: Caller, buildings: list[Building], document: Mapping[str, Any]
) -> Future[dict[str, Any]]:
    """``relocalise_in`` on the relocalisation lanes: the future of its answer (or of its
    KeyframeError). Raises RelocalisationBusy when the caller's share or its lane is full."""

    def work() -> dict[str, Any]:
        try:
            return relocalise_in(buildings, document)
        finally:
            close_old_connections()  # this thread's, after the keyframe index's queries

    return relocalisation_lanes().submit(caller, work)


def relocalise_in(buildings: Iterable[Building], document: Mapping[str, Any]) -> dict[str, Any]:
    """Answer a relocalisation request (``images``, optional ``depth``, ``camera_info``,
    ``mount``, ``submap``) against the keyframes of ``buildings`` (the ones the caller
    may use and named): the best answer of any, as the service's response fields."""
    limit = settings.CLOUDNAV_MAX_IMAGE_PIXELS
    images = [
        grey_image(item, limit, f"images[{i}]")
        for i, item in enumerate(image_list(document.get("images")))
    ]
    if document.get("depth") is not None:
        depth_image(document["depth"], images[0].shape, limit)  # checked, unused (docs/design.md)
    intrinsics = intrinsics_of(document.get("camera_info"), images[0].shape)
    if any(image.shape != images[0].shape for image in images):
        raise KeyframeError("images", "every image must have the same size")
    mount = mount_of(document.get("mount"))
    submap = _text(document.get("submap"), "submap")
    extractor = FeatureExtractor(default_vocabulary())
    frames = [_frame(extractor, image) for image in images]
    best: tuple[Building, Answer] | None = None
    for building in buildings:
        answer = relocalise(store.INDEXES.of(building), frames, intrinsics, mount, submap)
        if best is None or (answer.localised, answer.inliers) > (
            best[1].localised,
            best[1].inliers,
        ):
            best = (building, answer)
    if best is None:
        return response_of(None, Answer(False, "no building to look in"))
    return response_of(*best)


def _frame(extractor: FeatureExtractor, image: Any) -> QueryFrame:
    pixels, descriptors = extractor.detect(image)
    return QueryFrame(pixels, descriptors, extractor.vocabulary.bag(descriptors))


def _text(value: Any, field: str) -> str:
    if value is None:
        return ""
    if not isinstance(value, str):
        raise KeyframeError(field, "a code is required")
    return value.strip()


def response_of(building: Building | None, answer: Answer) -> dict[str, Any]:
    """The service's response fields of ``answer`` in ``building``."""
    localised = answer.localised and building is not None
    x, y, yaw = answer.pose
    return {
        "localised": localised,
        "map_id": f"{building.code}/{answer.submap}" if localised and building else "",
        "pose": {"x": x, "y": y, "yaw": yaw} if localised else {"x": 0.0, "y": 0.0, "yaw": 0.0},
        "covariance": [float(v) for v in answer.covariance.ravel()] if localised else [0.0] * 9,
        "inliers": int(answer.inliers),
        "keyframes": list(answer.keyframes) if localised else [],
        "image": int(answer.image),
        "reason": "" if localised else (answer.reason or "not localised"),
    }
