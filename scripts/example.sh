#!/usr/bin/env bash
# Set up rigkit in .venv and run the main job on the bundled example capture:
# depth map + previews from capture/example, then its accuracy against ground truth.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e .
F=$(.venv/bin/python -c "import yaml; print(yaml.safe_load(open('capture/example/scene.yaml'))['focal_px'])")
.venv/bin/rigkit depth capture/example/left.png capture/example/right.png capture/example/back.png \
    --focal-px "$F" --baseline-lr 2 --baseline-lb 2 --out out/example.npy --preview
.venv/bin/rigkit eval capture/example --depth-dir out --csv out/example-eval.csv
echo "previews: out/example.png (depth), out/example.sigma.png (uncertainty)"
