"""Benchmarks: each module offers add_arguments(parser) and run(options) to `manage.py bench`."""
