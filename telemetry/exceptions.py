"""Errors of the rosbridge server; ``telemetry.rosbridge.replies`` maps each to its
rosbridge answer.

No Django here: the domain modules raise these, and the robot agent may import them.
"""

from __future__ import annotations

from typing import Any


class RosbridgeError(Exception):
    """Base of every error answered on a rosbridge connection.

    ``op`` and ``id`` name the frame at fault (when known), so the answer can carry them.
    """

    level = "error"

    def __init__(self, message: str, *, op: str | None = None, id: Any = None) -> None:
        super().__init__(message)
        self.message = message
        self.op = op
        self.id = id


class BadFrame(RosbridgeError):
    """The frame is not a valid rosbridge operation: not JSON, not an object, no or unknown
    ``op``, a field of the wrong type, or over the size limit."""


class InvalidName(BadFrame):
    """A topic, service or action name is not a valid ROS name."""


class TypeConflict(RosbridgeError):
    """A topic is advertised, published or subscribed with a type other than its own."""


class UnknownTopic(RosbridgeError):
    """A topic is used without a type before anyone established it."""


class NotAllowed(RosbridgeError):
    """The connection's principal may not do this to this name."""


class ServiceFailed(RosbridgeError):
    """A service call cannot be answered; the caller gets ``result: false`` and the reason."""


class ActionFailed(RosbridgeError):
    """An action goal cannot be carried out; the caller gets an ``action_result`` that failed."""


class ServerFault(RosbridgeError):
    """The server could not carry a frame out (a shared store such as Redis did not answer,
    or a bug); the caller is told, the frame is dropped and the connection stays."""


class LimitReached(RosbridgeError):
    """The connection (or the server as a whole) holds as much of something as it may:
    subscriptions, advertisements, pending calls, parameters or fragments."""


class PoseRefused(RosbridgeError):
    """A goal or initial pose no robot could stand at (in an obstacle, in unknown space,
    outside its sub-map, out of reach, or naming no sub-map): refused where it was sent."""
