#!/usr/bin/env bash
# Set up rigkit with its test, experiments and cluster extras in .venv at the locked
# versions (requirements/lock.txt), then run lint, the layers contract (import-linter,
# see pyproject.toml and docs/architecture.md), type check and tests (all of them; see
# "Testing" in README.md). Arguments after the script's name go to pytest.
#
#   bash scripts/test.sh --latest [PYTEST ARGS]   the same in .venv-latest, on the newest
#                                                 releases pyproject.toml allows
set -euo pipefail
cd "$(dirname "$0")/.."
venv=.venv mode=""
if [[ "${1:-}" == "--latest" ]]; then
    venv=.venv-latest mode=--latest
    shift
fi
bash scripts/setup.sh "$venv" test,experiments,cluster $mode
echo "versions: $("$venv/bin/python" -m pip freeze 2>/dev/null \
    | grep -iE '^(numpy|scipy|opencv-python-headless|textual|dask)==' | paste -sd' ' || true)"
"$venv/bin/ruff" check rigkit tests benchmarks
"$venv/bin/lint-imports"
"$venv/bin/mypy" rigkit benchmarks
# Every test, slow ones included, in one worker process per core (pytest-xdist), a test
# file per worker at a time so that its module fixtures are built once; `-n 0` after the
# script's name runs them in this process. Skipped tests are listed with their reasons
# (-rs) and the slowest are named (--durations), so neither goes unseen.
"$venv/bin/python" -m pytest -n auto --dist loadfile -rs --durations=15 "$@"
