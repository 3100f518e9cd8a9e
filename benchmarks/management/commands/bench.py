"""``python manage.py bench NAME [options]``: run one benchmark or experiment by name."""

from __future__ import annotations

import argparse
from typing import Any

from django.core.management.base import BaseCommand, CommandError, CommandParser

from benchmarks import runner


class Command(BaseCommand):
    help = "Run a benchmark or an experiment: `bench` lists them, `bench NAME --help` its options."

    def add_arguments(self, parser: CommandParser) -> None:
        parser.add_argument("name", nargs="?", help="the benchmark or experiment")
        parser.add_argument("options", nargs=argparse.REMAINDER, help="its options")

    def handle(self, *args: Any, name: str | None, options: list[str], **_: Any) -> None:
        code = runner.main([name, *options] if name else [], prog="manage.py bench")
        if code:
            what = f"bench {name} ended with exit code {code}" if name else "name one of them"
            raise CommandError(what, returncode=code)
