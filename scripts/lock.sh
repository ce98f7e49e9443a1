#!/usr/bin/env bash
# Refresh requirements/lock.txt: install the newest releases pyproject.toml allows into
# .venv-latest, run the whole suite on them (scripts/test.sh --latest), and only if it
# passes write what was installed as the new lock. Review `git diff requirements/` and
# commit it with the suite's result; scripts/test.sh and scripts/example.sh then install
# exactly those versions.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/test.sh --latest "$@"
{
    echo "# The versions the whole suite last passed on (scripts/lock.sh, $(date -u +%F),"
    echo "# Python $(.venv-latest/bin/python -c 'import platform; print(platform.python_version())'), $(uname -sm))."
    echo "# Constraints for pip: scripts/setup.sh installs with PIP_CONSTRAINT set to this file."
    .venv-latest/bin/python -m pip freeze --all --exclude-editable | grep -v '^rigkit' | sort -f
} > requirements/lock.txt.new
mv requirements/lock.txt.new requirements/lock.txt
echo "requirements/lock.txt written: $(grep -vc '^#' requirements/lock.txt) packages"
