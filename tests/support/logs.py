"""What a test shows of a process's log when it fails."""

from __future__ import annotations

from pathlib import Path


def tail(log: Path, lines: int = 30) -> str:
    """The last ``lines`` lines of ``log``, undecodable bytes replaced."""
    return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])
