"""Benchmarks run by ``python manage.py bench NAME ...`` or ``python -m benchmarks NAME ...``.

Each module here is one benchmark: it exposes ``add_arguments(parser)`` (argparse) and
``run(options) -> None``, and its docstring's first line is its help. They are measuring
tools, not tests: they start what they measure as separate processes and print figures.
``runner`` runs them and the simulator's experiments by name; this package is a Django app
only to give ``manage.py`` its ``bench`` command, and the apps import nothing of it.
"""
