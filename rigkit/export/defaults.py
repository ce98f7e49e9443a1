"""What export and ``rigkit export --help`` share: the words ``--vertical`` takes for the
heights' datum (:func:`rigkit.export.crs.map_crs`). One place for both, in a module that
imports nothing, so that building the command line's parser loads neither PROJ nor the
exporters."""

from __future__ import annotations

VERTICAL_RECORDED = "recorded"
"""Heights as the tripod's height was recorded (the default)."""
VERTICAL_ELLIPSOIDAL = "ellipsoidal"
"""Heights above the output CRS's ellipsoid."""
