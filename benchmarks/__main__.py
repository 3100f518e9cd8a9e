"""``python -m benchmarks NAME [options]``: run one benchmark or experiment (see ``runner``)."""

from __future__ import annotations

import sys

from benchmarks.runner import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
