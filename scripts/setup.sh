#!/usr/bin/env bash
# Create (or update) a virtual environment with rigkit installed in it, editable.
#
#   bash scripts/setup.sh VENV EXTRAS            the locked versions (requirements/lock.txt)
#   bash scripts/setup.sh VENV EXTRAS --latest   the newest releases pyproject.toml allows
#
# EXTRAS is e.g. "test,experiments,cluster", or "" for rigkit alone. The lock pins every
# package, pip, setuptools and wheel included, and reaches the build of rigkit itself
# through PIP_CONSTRAINT; how it is made: README.md, "Testing".
set -euo pipefail
cd "$(dirname "$0")/.."
venv=$1 extras=${2:-} mode=${3:-}
target="."
[[ -n "$extras" ]] && target=".[$extras]"
if [[ "$mode" == "--latest" ]]; then
    rm -rf "$venv"  # nothing carried over from an earlier resolution
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --upgrade pip setuptools wheel
    "$venv/bin/python" -m pip install --quiet --upgrade --upgrade-strategy eager -e "$target"
else
    python3 -m venv "$venv"
    export PIP_CONSTRAINT="$PWD/requirements/lock.txt"
    "$venv/bin/python" -m pip install --quiet --upgrade pip setuptools wheel
    "$venv/bin/python" -m pip install --quiet -e "$target"
fi
