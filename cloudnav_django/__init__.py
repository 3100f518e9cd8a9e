"""The server's Django plumbing the apps share, below all three and above the core.

What the apps' background writers, views and streams need of the server, none of it
about buildings, robots or telemetry: writing a batch of rows that one bad row never
blocks (``batches``), the database out of reach answered 503 and reported once in a while
(``outage``), heavy HTTP work within a memory budget (``heavy``), and when a viewer's
socket under daphne can take the next write (``readiness``). Nothing here imports maps,
robots, telemetry or cloudnav_web (import-linter's layers, pyproject.toml).
"""
