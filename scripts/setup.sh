#!/usr/bin/env bash
# Create (or update) a virtual environment with rigkit installed in it, editable.
#
#   bash scripts/setup.sh VENV EXTRAS            the locked versions (requirements/lock.txt)
#   bash scripts/setup.sh VENV EXTRAS --latest   the newest releases pyproject.toml allows
#
# EXTRAS is e.g. "test,experiments,cluster", or "" for rigkit alone. The lock pins every
# package, pip, setuptools and wheel included, and reaches the build of rigkit itself
# through PIP_CONSTRAINT; how it is made: README.md, "Testing". The checkout may lie at a
# path with spaces (the lock is then given to pip as a file: URL, which pip does not split
# at spaces as it does a PIP_CONSTRAINT path). A VENV whose python no longer runs (its
# link dangles: the Python it was made with is gone) is made anew.
set -euo pipefail
usage="usage: bash scripts/setup.sh VENV [EXTRAS] [--latest]   (e.g. .venv test,experiments)"
if [[ $# -lt 1 || -z "$1" || $# -gt 3 ]]; then
    echo "$usage" >&2
    exit 2
fi
cd "$(dirname "$0")/.."
venv=$1 extras=${2:-} mode=${3:-}
if [[ -n "$mode" && "$mode" != "--latest" ]]; then
    echo "setup.sh: $mode: expected --latest; $usage" >&2
    exit 2
fi
target="."
[[ -n "$extras" ]] && target=".[$extras]"
if [[ -e "$venv" || -L "$venv" ]] && ! "$venv/bin/python" -c "" 2>/dev/null; then
    if [[ ! -f "$venv/pyvenv.cfg" && -n "$(ls -A "$venv" 2>/dev/null)" ]]; then
        echo "setup.sh: $venv exists and is no virtual environment; remove it or give another VENV" >&2
        exit 2
    fi
    if [[ -f "$venv/pyvenv.cfg" ]]; then
        echo "setup.sh: $venv/bin/python does not run (the Python it was made with is gone?); making $venv anew" >&2
        python3 -m venv --clear "$venv"
    fi
fi
if [[ "$mode" == "--latest" ]]; then
    rm -rf "$venv"  # nothing carried over from an earlier resolution
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --upgrade pip setuptools wheel
    "$venv/bin/python" -m pip install --quiet --upgrade --upgrade-strategy eager -e "$target"
else
    python3 -m venv "$venv"
    PIP_CONSTRAINT="$(python3 -c 'import pathlib, sys; print(pathlib.Path(sys.argv[1]).resolve().as_uri())' requirements/lock.txt)"
    export PIP_CONSTRAINT
    "$venv/bin/python" -m pip install --quiet --upgrade pip setuptools wheel
    "$venv/bin/python" -m pip install --quiet -e "$target"
fi
