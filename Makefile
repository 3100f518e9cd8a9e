# CloudNav: the README names `make demo` and `make test`; the rest are their parts.
PY := .venv/bin/python
BIN := .venv/bin
export CLOUDNAV_TEST_REDIS_URL ?= redis://127.0.0.1:6379/9
export CLOUDNAV_TEST_POSTGRES_URL ?= postgres://postgres:postgres@127.0.0.1:5432/postgres

.PHONY: setup services demo demo-scaled test unit lint typecheck pytest bench format ros2

setup:
	bash scripts/setup.sh

services:
	bash scripts/services.sh

## The ROS 2 robot side's virtualenvs (Jazzy, Kilted), built once and cached; the ROS 2
## tests build them too when absent.
ros2:
	bash scripts/ros2_env.sh jazzy
	bash scripts/ros2_env.sh kilted

## Set up, seed the demo building and run the server (http://127.0.0.1:8000) with simulated robots.
demo: setup
	bash scripts/demo.sh

## The demo in the scaled mode: PROCESSES (3) daphne processes behind nginx on one port,
## with Redis and PostgreSQL started where none answers (README, "A real front").
demo-scaled: setup
	PROCESSES=$${PROCESSES:-3} bash scripts/demo.sh

## Set up, start Redis and PostgreSQL where none answers, lint, type-check and run every test.
test: setup services lint typecheck pytest

## The fast tests alone (under two minutes): no live server, browser, Redis or PostgreSQL,
## nothing that commits to the database for other threads, nothing marked slow.
unit:
	$(BIN)/pytest -n $(TEST_WORKERS) -m "not live and not transactional and not browser and not scaled and not slow"

## ruff (lint, unused arguments, format), the import contracts, ESLint on static/js, and
## models without their migration.
lint:
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports
	node_modules/.bin/eslint --max-warnings 0 static/js tests/js
	$(PY) manage.py makemigrations --check --dry-run

## mypy, strict on the source (pyproject.toml).
typecheck:
	$(BIN)/mypy .

# The coverage floor is stated in the README.
COVERAGE_FLOOR := 80
# pytest-xdist workers: the tests mostly wait on servers, robots and browsers they start,
# so two share two cores (each worker has its own Redis database, ROS 2 domains and
# keyframe directory; tests/fixtures_live.py).
TEST_WORKERS ?= 2

pytest:
	$(BIN)/pytest -n $(TEST_WORKERS) --durations=30 --cov --cov-report=term --cov-fail-under=$(COVERAGE_FLOOR)

format:
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

## python manage.py bench NAME ... (see README)
bench: setup
	$(PY) manage.py bench $(ARGS)
