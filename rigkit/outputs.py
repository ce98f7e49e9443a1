"""Writing a command's output files so that they appear together or not at all."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rigkit.preview import write_png

Content = str | np.ndarray


def write_file(path: Path, content: Content) -> None:
    """Text (UTF-8), or an array as ``.png`` (BGR/grey uint8) or ``.npy``, by suffix."""
    if isinstance(content, str):
        path.write_text(content, encoding="utf-8")
    elif path.suffix == ".png":
        write_png(path, content)
    elif path.suffix == ".npy":
        np.save(path, content)
    else:
        raise ValueError(f"{path}: no writer for an array with this suffix")


def write_together(folder: Path, files: Mapping[str, Content]) -> None:
    """Write ``files`` (name -> content) into ``folder``: all of them to a temporary
    folder inside it first, then each renamed into place, so a failure never leaves a
    mix of old and new outputs that looks complete. OSError if a write fails."""
    with tempfile.TemporaryDirectory(dir=folder, prefix=".rigkit-") as tmp:
        for name, content in files.items():
            write_file(Path(tmp) / name, content)
        for name in files:
            os.replace(Path(tmp) / name, folder / name)
