"""``python -m robots.agent.experiments NAME [options]``: run one experiment by name."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence

from robots.agent.experiments import localisation, tag_range

EXPERIMENTS: dict[str, Callable[[Sequence[str]], int]] = {
    "tag-range": tag_range.main,
    "localisation": localisation.main,
}


def main(argv: Sequence[str]) -> int:
    """Dispatch to the experiment named first in ``argv``; 2 for an unknown name."""
    if not argv or argv[0] not in EXPERIMENTS:
        names = ", ".join(sorted(EXPERIMENTS))
        print(f"usage: python -m robots.agent.experiments {{{names}}} [options]", file=sys.stderr)
        return 2
    return EXPERIMENTS[argv[0]](argv[1:])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
