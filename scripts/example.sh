#!/usr/bin/env bash
# Set up rigkit in .venv and run the main job on the bundled example session: depth,
# previews and rangefinder-vs-estimate comparisons for capture/example, the report of
# those comparisons, and (the example being synthetic) accuracy against ground truth.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh .venv ""  # the locked versions (requirements/lock.txt)
.venv/bin/rigkit session show capture/example
.venv/bin/rigkit process capture/example
.venv/bin/rigkit report capture/example --out out/example-report
.venv/bin/rigkit eval capture/example --csv out/example-eval.csv
echo "previews: capture/example/results/depth.png, left.png (targets marked), sigma.png"
echo "report:   out/example-report/ (report.txt, estimate_vs_laser.png, error_vs_range.png)"
# The last line says whether the example meets the goal (rigkit eval --goal exits 1 if not).
.venv/bin/rigkit eval capture/example --goal | tail -n 1
