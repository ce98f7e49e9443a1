#!/usr/bin/env bash
# Set up rigkit with its test, experiments and cluster extras in .venv, then run lint, the
# layers contract (import-linter, see pyproject.toml and docs/architecture.md), type check
# and tests (all of them; see "Testing" in README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e '.[test,experiments,cluster]'
.venv/bin/ruff check rigkit tests benchmarks
.venv/bin/lint-imports
.venv/bin/mypy rigkit
# Every test, slow ones included, in one worker process per core (pytest-xdist), a test
# file per worker at a time so that its module fixtures are built once; `-n 0` after the
# script's name runs them in this process.
.venv/bin/python -m pytest -n auto --dist loadfile "$@"
