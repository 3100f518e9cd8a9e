"""``python -m robots.agent``: run simulated robots against a CloudNav server.

One robot::

    python -m robots.agent --server http://127.0.0.1:8000 --token cnr_...

Many in one process, with the tokens ``manage.py seed_demo`` wrote::

    python -m robots.agent --server http://127.0.0.1:8000 \
        --tokens-file var/demo_tokens.json --count 3

``--changes 7`` runs a building that differs from its stored maps in ways drawn from
seed 7 (``robots/agent/sim/changes.py``).
``--planner teb`` drives with the timed elastic band instead of the dynamic window.
``--sensors rgbd`` gives the robots an RGB-D camera and no laser: each makes its scan
from depth, as ``depthimage_to_laserscan`` does, for its own obstacle avoidance.
``--people 8 --people-seed 3`` puts eight people on seeded routes through the building;
the robots see them, and one another, in their lasers and cameras.
``--time-scale 4`` runs the simulation four times faster than the wall clock (every rate
and timeout of the robot is in simulated time). Ctrl-C (or SIGTERM) stops the robots.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import logging
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

from cloudnav_core.params import RobotConfig
from robots.agent.fleet import (
    FleetOptions,
    add_robot_arguments,
    build_fleet,
    parse_pose,
    run_fleet,
)
from robots.agent.sim.changes import plan_changes


def arguments(argv: Sequence[str] | None = None) -> argparse.Namespace:
    summary = (__doc__ or "").split("\n")[0]
    parser = argparse.ArgumentParser(prog="python -m robots.agent", description=summary)
    parser.add_argument("--server", required=True, help="the server, http://host:port or ws://...")
    credentials = parser.add_mutually_exclusive_group(required=True)
    credentials.add_argument("--token", help="one robot's token")
    credentials.add_argument("--tokens-file", type=Path, help="JSON {robot name: token}")
    parser.add_argument("--count", type=int, default=1, help="robots from --tokens-file")
    add_robot_arguments(parser)
    parser.add_argument("--start", type=parse_pose, help="x,y,yaw (default: the demo's start)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--changes",
        type=int,
        metavar="SEED",
        help="run a building that differs from its maps: changes drawn from SEED "
        "(moved and new furniture, a closed door, a new wall, an unmapped room)",
    )
    parser.add_argument("--log-level", default="INFO")
    options = parser.parse_args(argv)
    if options.time_scale <= 0 or options.count < 1 or options.people < 0:
        parser.error("--time-scale must be positive, --count at least 1, --people at least 0")
    return options


def tokens_of(options: argparse.Namespace) -> list[tuple[str, str]]:
    """``(name, token)`` of each robot to run. Raises SystemExit on a short tokens file."""
    if options.token:
        return [("robot", options.token)]
    known = json.loads(options.tokens_file.read_text())
    if len(known) < options.count:
        raise SystemExit(f"{options.tokens_file} holds {len(known)} robot(s), not {options.count}")
    return list(known.items())[: options.count]


async def main(options: argparse.Namespace) -> None:
    fleet_options = FleetOptions(
        server=options.server,
        start=options.start,
        particles=options.particles,
        seed=options.seed,
        robot=RobotConfig(
            camera_rate=options.camera_rate,
            camera_timecode=options.camera_timecode,
            depth_rate=options.depth_rate,
            raw_depth=options.raw_depth,
            local_planner=options.planner,
            sensors=options.sensors,
        ),
        changes=None if options.changes is None else plan_changes(options.changes),
        visual=options.visual,
        people=options.people,
        people_seed=options.people_seed,
    )
    fleet = build_fleet(tokens_of(options), fleet_options)
    running = asyncio.create_task(run_fleet(fleet, options.time_scale))
    loop = asyncio.get_running_loop()
    for stop in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(stop, running.cancel)
    with contextlib.suppress(asyncio.CancelledError):
        await running


if __name__ == "__main__":
    parsed = arguments()
    logging.basicConfig(
        level=parsed.log_level.upper(),
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    # httpx logs every request at INFO: the bundle check every 2 s, unchanged or not. The
    # supervisor says itself when a bundle was downloaded.
    if logging.getLogger().level > logging.DEBUG:
        logging.getLogger("httpx").setLevel(logging.WARNING)
    asyncio.run(main(parsed))
