"""An orderly end under daphne: every task finished and every worker thread joined.

On SIGTERM daphne cancels the applications it started and stops its reactor, but tasks the
applications started themselves (Django's disconnect listener of a streaming response,
the hub's and the video relay's tasks, encoders' work in threads) were left suspended.
The interpreter then destroyed them while it tore itself down, and that garbage
collection of suspended coroutines ended the process with a segmentation fault.

``install`` adds a step to the reactor's shutdown, beside daphne's own: cancel
every remaining task and wait for them (so streams leave their pipelines and encoders
close), then stop and join every registered worker (``cloudnav_core.workers.REGISTRY``:
recorder, encoders, mapping, upkeep, keyframes, relocalisation), before the reactor stops
and the interpreter exits.
"""

from __future__ import annotations

import asyncio
import logging
import sys

from cloudnav_core.workers import REGISTRY

logger = logging.getLogger(__name__)

# Tasks that ignore cancellation for longer than this are left behind, logged.
GRACE = 5.0


def install() -> None:
    """Under daphne, finish tasks and threads when the reactor shuts down (no-op elsewhere).

    Only a reactor already installed (daphne's) is used: importing one would install it.
    """
    reactor = sys.modules.get("twisted.internet.reactor")
    if reactor is None or not hasattr(reactor, "_asyncioEventloop"):
        return
    from twisted.internet.defer import Deferred

    def finish() -> Deferred[None]:
        return Deferred.fromFuture(asyncio.ensure_future(finish_tasks()))

    # "before", as daphne's own: in "during" the reactor stops the event loop first.
    reactor.addSystemEventTrigger("before", "shutdown", finish)


async def finish_tasks(grace: float = GRACE) -> None:
    """Cancel every task of the running loop but this one and wait for them (and for those
    they start while they end), at most ``grace`` seconds; then stop and join the registered
    workers, at most ``grace`` seconds more."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + grace
    while (tasks := _others()) and loop.time() < deadline:
        for task in tasks:
            task.cancel()
        await asyncio.wait(tasks, timeout=deadline - loop.time())
    if tasks:
        logger.warning("shutdown: %d tasks did not finish: %r", len(tasks), tasks)
    await REGISTRY.finish(grace)
    await loop.shutdown_default_executor()


def _others() -> set[asyncio.Task[object]]:
    current = asyncio.current_task()
    return {task for task in asyncio.all_tasks() if task is not current}
