"""The one runner of the benchmarks and the experiments, by name.

``python -m benchmarks NAME [options]`` and ``python manage.py bench NAME [options]``
both come here. A benchmark is a module of this package with ``add_arguments(parser)``
(argparse) and ``run(options)``, whose docstring's first line is its help, named after
the module or its ``NAME`` (``ros-bridge``, which no module name can spell); an experiment
is an entry of ``robots.agent.experiments``' table (``main(argv) -> int``), which the
robot side also runs without the server's packages (``python -m robots.agent.experiments``).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import ModuleType

import benchmarks
from robots.agent.experiments.__main__ import EXPERIMENTS


@dataclass(frozen=True)
class Program:
    """A benchmark or an experiment: its one-line help, and its ``main(argv) -> exit code``."""

    summary: str
    main: Callable[[Sequence[str]], int]


def benchmark_modules() -> dict[str, ModuleType]:
    """Return every module of the ``benchmarks`` package that defines a benchmark."""
    found = {}
    for info in pkgutil.iter_modules(benchmarks.__path__):
        if info.ispkg or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"benchmarks.{info.name}")
        if hasattr(module, "add_arguments") and hasattr(module, "run"):
            found[getattr(module, "NAME", info.name)] = module
    return found


def programs() -> dict[str, Program]:
    """Return every benchmark and experiment by name."""
    found = {name: _benchmark(name, module) for name, module in benchmark_modules().items()}
    for name, main in EXPERIMENTS.items():
        found[name] = Program(f"experiment: {_summary(sys.modules[main.__module__], name)}", main)
    return dict(sorted(found.items()))


def main(argv: Sequence[str], prog: str = "python -m benchmarks") -> int:
    """Run the program named first in ``argv`` with the rest; 2, and the list, for no name
    or an unknown one."""
    found = programs()
    if not argv or argv[0] not in found:
        listing = "".join(f"\n  {name:<14} {program.summary}" for name, program in found.items())
        print(
            f"usage: {prog} NAME [options]  (NAME --help for its options){listing}", file=sys.stderr
        )
        return 2
    return found[argv[0]].main(argv[1:])


def _benchmark(name: str, module: ModuleType) -> Program:
    summary = _summary(module, name)

    def main(argv: Sequence[str]) -> int:
        parser = argparse.ArgumentParser(prog=f"bench {name}", description=summary)
        module.add_arguments(parser)
        module.run(vars(parser.parse_args(argv)))
        return 0

    return Program(summary, main)


def _summary(module: ModuleType, name: str) -> str:
    return (module.__doc__ or name).strip().splitlines()[0]
