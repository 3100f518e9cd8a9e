"""STOP: halt a robot whatever moves it.

``RobotStop.stop`` is the one operation behind every STOP button (``/cloudnav/stop``):

- the teleop lock is withdrawn from whoever holds it, so their ``cmd_vel`` no longer
  passes, and the robot is sent a zero Twist;
- the robot's active goal is cancelled whoever sent it (a page, a mission, the API, another
  operator), by calling the robot's own ``cancel_goal`` from the server, on the process the
  robot is connected to (through the relay when that is another one);
- the robot's running missions are paused, so no next waypoint is sent;
- a ``robot_stopped`` event names who stopped it and what the stop did.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Callable
from typing import Any

from channels.db import database_sync_to_async

from cloudnav_core import topics
from robots import missions
from telemetry.domain.encoding import Wire
from telemetry.events import EventLog
from telemetry.rosbridge.connection import Connection
from telemetry.rosbridge.cross_process import CrossProcess
from telemetry.rosbridge.server_services import Stopped
from telemetry.rosbridge.service_calls import ServiceCalls
from telemetry.rosbridge.teleop_gate import TeleopGate

# The relay message asking the process a robot is connected to to halt it there.
STOP_REQUEST = "rb.stop"
# How long STOP waits for the robot to answer its ``cancel_goal``.
CANCEL_WAIT_S = 3.0


class RobotStop:
    """STOP for the robots of every process (see the module's docstring)."""

    def __init__(
        self,
        calls: ServiceCalls,
        teleop: TeleopGate,
        events: EventLog,
        relay: Callable[[], CrossProcess],
    ) -> None:
        self._calls = calls
        self._teleop = teleop
        self._events = events
        self._relay = relay

    async def stop(self, robot: str, conn: Connection) -> Stopped:
        """Halt ``robot`` for the person on ``conn`` (already allowed to drive it; a lock
        they hold themselves they keep) and say what was done."""
        by = conn.principal
        # Missions first, so the runner sends no next waypoint once the goal is cancelled.
        paused = await database_sync_to_async(missions.pause_for_stop)(
            robot, by.label, by.drive_buildings
        )
        holder = await self._teleop.locks.withdraw(robot, keep=conn.key)
        stopped = Stopped(await self._halt(robot), paused, holder)
        self._events.stopped(robot, by.label, stopped.as_values())
        return stopped

    async def _halt(self, robot: str) -> str:
        """Zero velocity and the goal cancelled where the robot is connected; return what
        is known of the goal."""
        service = topics.robot_topic(robot, topics.CANCEL_GOAL)
        if self._calls.services.provider(service) is None:
            found = await self._relay().find("services", service)
            self._teleop.stop_robot(robot)  # reaches the robot on any process
            if found is None:
                return "the robot is not connected"
            self._relay().send(found[0], {"type": STOP_REQUEST, "robot": robot})
            return "cancel sent to the robot's server process"
        return await self.halt_here(robot)

    async def halt_here(self, robot: str) -> str:
        """Zero velocity, and cancel the goal of ``robot``, connected to this process;
        return what the robot answered."""
        self._teleop.stop_robot(robot)
        service = topics.robot_topic(robot, topics.CANCEL_GOAL)
        caller = ServerCaller()
        if not self._calls.call_as_server(service, {}, caller):
            return "the robot serves no cancel_goal"
        try:
            answer = await asyncio.wait_for(caller.answer, CANCEL_WAIT_S)
        except TimeoutError:
            return "the robot did not answer the cancel"
        return _goal_outcome(answer)


class ServerCaller:
    """The server itself as the caller of one service: the answer lands in ``answer``."""

    def __init__(self) -> None:
        self.key = f"server-call-{id(self)}"
        self.answer: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()

    def deliver(self, wire: Wire) -> None:
        if self.answer.done():
            return
        try:
            frame = json.loads(b"".join(wire.payloads))
        except ValueError:
            frame = {"result": False, "values": "an answer that is not JSON"}
        self.answer.set_result(frame if isinstance(frame, dict) else {})


def _goal_outcome(answer: dict[str, Any]) -> str:
    values = answer.get("values")
    if not answer.get("result"):
        return f"cancel failed: {values}"
    if isinstance(values, dict):
        return str(values.get("message") or ("cancelled" if values.get("success") else "none"))
    return "cancelled"
