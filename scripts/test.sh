#!/usr/bin/env bash
# Set up rigkit with its test, experiments and cluster extras in .venv, then run lint, the
# layers contract (import-linter, see pyproject.toml and docs/architecture.md), type check
# and tests.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e '.[test,experiments,cluster]'
.venv/bin/ruff check rigkit tests benchmarks
.venv/bin/lint-imports
.venv/bin/mypy rigkit
.venv/bin/python -m pytest "$@"
