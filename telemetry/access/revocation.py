"""Access changes, announced after they commit and applied to open connections and streams.

What a connection was admitted with can change while it is open: a robot's token is
rotated, a robot is renamed, relinked or deleted, a person loses a membership or a group,
has their role in a building changed, is deleted or signs out. Django signals turn each
into an ``AccessChange``, announced once the transaction commits
(``transaction.on_commit``): in scaled mode to every server process over Redis
(``access_channel``, which each relay listens to), else to the access review of each hub
of this process (``listen``). Each process then re-reads the robots named (one query,
never per message), updates its ``Registry``, closes the rosbridge connections and video
streams that depended on what was revoked (``revoked``), and takes every other
connection's decisions again (``AccessReview.access_changed``).
"""

from __future__ import annotations

import asyncio
import contextvars
import json
import logging
import weakref
from collections.abc import Callable, Coroutine, Iterable
from dataclasses import dataclass, field
from typing import Any

from django.conf import settings
from django.contrib.auth import get_user_model
from django.contrib.auth.signals import user_logged_out
from django.db import transaction
from django.db.models.signals import m2m_changed, post_delete, post_save, pre_delete, pre_save

from maps.models import Building, Membership
from robots.models import Robot
from telemetry.access.rules import Owner, Principal

logger = logging.getLogger(__name__)

ACCESS_CHANNEL = "cloudnav:rb:access"


def access_channel(redis: Any) -> str:
    """The Redis channel of access changes for the database ``redis`` uses: Redis shares
    its channels across databases, and deployments (or test runs) on one server must not
    hear each other's."""
    db = redis.connection_pool.connection_kwargs.get("db", 0)
    return f"{ACCESS_CHANNEL}:{db}"


@dataclass
class AccessChange:
    """Robots to read again; people and sessions whose connections close."""

    robots: set[int] = field(default_factory=set)
    users: set[int] = field(default_factory=set)
    sessions: set[str] = field(default_factory=set)

    def message(self) -> dict[str, Any]:
        return {
            "type": "rb.access",
            "robots": sorted(self.robots),
            "users": sorted(self.users),
            "sessions": sorted(self.sessions),
        }

    @classmethod
    def of(cls, message: dict[str, Any]) -> AccessChange:
        return cls(set(message["robots"]), set(message["users"]), set(message["sessions"]))


@dataclass(frozen=True)
class RobotRecord:
    """A robot as a revocation compares it: owner of its names, and its token's digest."""

    owner: Owner
    token_hash: str


def robot_records(pks: Iterable[int]) -> dict[int, RobotRecord | None]:
    """Read robots ``pks`` as they are now; None for a deleted one."""
    found: dict[int, RobotRecord | None] = dict.fromkeys(pks)
    for robot in Robot.objects.filter(pk__in=list(found)).prefetch_related("buildings"):
        buildings = frozenset(b.pk for b in robot.buildings.all())
        found[robot.pk] = RobotRecord(Owner(robot.name, buildings, robot.pk), robot.token_hash)
    return found


def revoked(
    principal: Principal, change: AccessChange, robots: dict[int, RobotRecord | None]
) -> bool:
    """True if what ``principal`` was admitted with no longer holds after ``change``.

    A robot's connections close when it is deleted, renamed, relinked or its token is
    rotated (it reconnects as it now is); a person's when they lost a membership or a
    role, were deleted or disabled, or signed out of the session they connected with."""
    if principal.user_id is not None and principal.user_id in change.users:
        return True
    if principal.robot is None:
        return principal.credential is not None and principal.credential in change.sessions
    if principal.robot_pk is None or principal.robot_pk not in robots:
        return False
    now = robots[principal.robot_pk]
    return (
        now is None
        or now.owner.robot != principal.robot
        or now.owner.buildings != principal.buildings
        or now.token_hash != principal.credential
    )


# ------------------------------------------------------------------ announcing

Review = Callable[[AccessChange], Coroutine[Any, Any, None]]

# In embedded mode, the access review of each started hub of this process, by its event
# loop (``listen``); in scaled mode every process's relay applies the changes instead.
_reviews: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, Review] = weakref.WeakKeyDictionary()


def listen(loop: asyncio.AbstractEventLoop, review: Review) -> None:
    """Have ``review(change)`` run on ``loop`` for each change announced in this process."""
    _reviews[loop] = review


def announce_on_commit(change: AccessChange) -> None:
    """Announce ``change`` once the current transaction commits (at once outside one)."""
    if change.robots or change.users or change.sessions:
        transaction.on_commit(lambda: announce(change))


def announce(change: AccessChange) -> None:
    """Tell every server process (scaled mode) or every hub of this one about ``change``."""
    try:
        if getattr(settings, "REDIS_URL", ""):
            import redis

            client = redis.Redis.from_url(settings.REDIS_URL)
            try:
                client.publish(access_channel(client), json.dumps(change.message()))
            finally:
                client.close()
            return
        for loop, review in list(_reviews.items()):
            if not loop.is_closed():
                # a fresh context: not this thread's (asgiref's executor state stays here)
                context = contextvars.Context()
                loop.call_soon_threadsafe(_apply, loop, review, change, context=context)
    except Exception:
        logger.exception("could not announce an access change")


def _apply(loop: asyncio.AbstractEventLoop, review: Review, change: AccessChange) -> None:
    loop.create_task(review(change))


# ------------------------------------------------------------------ signals


def _robot_saved(instance: Robot, **kwargs: Any) -> None:
    announce_on_commit(AccessChange(robots={instance.pk}))


def _robot_deleted(instance: Robot, **kwargs: Any) -> None:
    announce_on_commit(AccessChange(robots={instance.pk}))


def _robot_buildings(instance: Any, action: str, reverse: bool, pk_set: Any, **kwargs: Any) -> None:
    """A robot linked to or unlinked from buildings (from either side)."""
    if action == "pre_clear" and reverse:
        instance._cloudnav_cleared = set(instance.robots.values_list("pk", flat=True))
        return
    if action not in ("post_add", "post_remove", "post_clear"):
        return
    if not reverse:
        robots = {instance.pk}
    elif action == "post_clear":
        robots = getattr(instance, "_cloudnav_cleared", set())
    else:
        robots = set(pk_set or ())
    announce_on_commit(AccessChange(robots=robots))


def _members(instance: Any, action: str, reverse: bool, pk_set: Any, **kwargs: Any) -> None:
    """People removed from a building lose what it gave them."""
    if action == "pre_clear" and not reverse:
        instance._cloudnav_cleared = set(instance.members.values_list("pk", flat=True))
        return
    if action not in ("post_remove", "post_clear"):
        return
    if reverse:
        users = {instance.pk}
    elif action == "post_clear":
        users = getattr(instance, "_cloudnav_cleared", set())
    else:
        users = set(pk_set or ())
    announce_on_commit(AccessChange(users=users))


def _membership_saving(instance: Any, **kwargs: Any) -> None:
    """Remember the role a membership had before this save."""
    if instance.pk is not None:
        held = Membership.objects.filter(pk=instance.pk).values_list("role", flat=True).first()
        instance._cloudnav_role_was = held


def _membership_saved(instance: Membership, created: bool, **kwargs: Any) -> None:
    """A person's role in a building changed: their connections close and reconnect with
    what the new role allows (a demoted operator loses teleop at once)."""
    was = getattr(instance, "_cloudnav_role_was", None)
    if not created and was is not None and was != instance.role:
        announce_on_commit(AccessChange(users={instance.user_id}))


def _membership_deleted(instance: Membership, **kwargs: Any) -> None:
    announce_on_commit(AccessChange(users={instance.user_id}))


def _groups(instance: Any, action: str, reverse: bool, **kwargs: Any) -> None:
    """A role taken away (a group removed from a user, or users from a group)."""
    if action not in ("post_remove", "post_clear"):
        return
    if reverse:
        users = set(kwargs.get("pk_set") or ()) or set(
            instance.user_set.values_list("pk", flat=True)
        )
    else:
        users = {instance.pk}
    announce_on_commit(AccessChange(users=users))


def _building_deleted(instance: Building, **kwargs: Any) -> None:
    robots = set(instance.robots.values_list("pk", flat=True))
    users = set(instance.members.values_list("pk", flat=True))
    announce_on_commit(AccessChange(robots=robots, users=users))


def _user_saved(instance: Any, created: bool, **kwargs: Any) -> None:
    if not created and not instance.is_active:
        announce_on_commit(AccessChange(users={instance.pk}))


def _user_deleted(instance: Any, **kwargs: Any) -> None:
    announce_on_commit(AccessChange(users={instance.pk}))


def _logged_out(request: Any, **kwargs: Any) -> None:
    key = getattr(getattr(request, "session", None), "session_key", None)
    if key:
        announce_on_commit(AccessChange(sessions={key}))


def connect_signals() -> None:
    User = get_user_model()
    uid = "cloudnav-revocation"
    post_save.connect(_robot_saved, sender=Robot, dispatch_uid=f"{uid}-robot-saved")
    post_delete.connect(_robot_deleted, sender=Robot, dispatch_uid=f"{uid}-robot-deleted")
    m2m_changed.connect(
        _robot_buildings, sender=Robot.buildings.through, dispatch_uid=f"{uid}-robot-buildings"
    )
    m2m_changed.connect(_members, sender=Building.members.through, dispatch_uid=f"{uid}-members")
    pre_save.connect(_membership_saving, sender=Membership, dispatch_uid=f"{uid}-membership-was")
    post_save.connect(_membership_saved, sender=Membership, dispatch_uid=f"{uid}-membership")
    post_delete.connect(
        _membership_deleted, sender=Membership, dispatch_uid=f"{uid}-membership-deleted"
    )
    m2m_changed.connect(_groups, sender=User.groups.through, dispatch_uid=f"{uid}-groups")
    pre_delete.connect(_building_deleted, sender=Building, dispatch_uid=f"{uid}-building")
    post_save.connect(_user_saved, sender=User, dispatch_uid=f"{uid}-user-saved")
    post_delete.connect(_user_deleted, sender=User, dispatch_uid=f"{uid}-user-deleted")
    user_logged_out.connect(_logged_out, dispatch_uid=f"{uid}-logout")
