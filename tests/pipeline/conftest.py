"""test_pipeline.py is kept byte for byte (the lead replaces it) and still imports the
evaluation from its old place, ``rigkit.evaluate``; it now lives in
``rigkit.synth.evaluate``. Remove this alias once test_pipeline.py imports that."""

from __future__ import annotations

import sys

import rigkit.synth.evaluate

sys.modules.setdefault("rigkit.evaluate", rigkit.synth.evaluate)
