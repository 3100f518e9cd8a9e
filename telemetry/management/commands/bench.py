"""``python manage.py bench NAME [options]``: run one benchmark module of ``benchmarks``."""

from __future__ import annotations

import importlib
import pkgutil
from types import ModuleType
from typing import Any

from django.core.management.base import BaseCommand, CommandParser

import benchmarks


def benchmark_modules() -> dict[str, ModuleType]:
    """Return every module of the ``benchmarks`` package that defines a benchmark."""
    found = {}
    for info in pkgutil.iter_modules(benchmarks.__path__):
        module = importlib.import_module(f"benchmarks.{info.name}")
        if hasattr(module, "add_arguments") and hasattr(module, "run"):
            found[info.name] = module
    return found


class Command(BaseCommand):
    help = "Run a benchmark: `bench NAME --help` lists its options."

    def add_arguments(self, parser: CommandParser) -> None:
        choices = parser.add_subparsers(dest="benchmark", required=True, metavar="NAME")
        for name, module in sorted(benchmark_modules().items()):
            summary = (module.__doc__ or name).strip().splitlines()[0]
            module.add_arguments(choices.add_parser(name, help=summary, description=summary))

    def handle(self, *args: Any, **options: Any) -> None:
        benchmark_modules()[options["benchmark"]].run(options)
