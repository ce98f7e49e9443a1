"""What Table 1 and ``rigkit experiments --help`` share: the methods it compares (the
default of ``--methods``), in a module that imports nothing, so that building the
command line's parser does not load the experiments."""

from __future__ import annotations

METHODS = ("rigkit", "paper", "loop-zhang", "sfm-mvs")
"""Table 1's methods: rigkit's pipeline, the paper's method as written, Loop & Zhang
rectification, SfM+MVS (COLMAP)."""
