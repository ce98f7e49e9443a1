"""Frame previews: textual-image when the terminal has a graphics protocol (Kitty's or
Sixel), else the plain half-block :class:`rigkit.tui.widgets.PixelView`.

textual-image asks the terminal what it supports when it is imported, which must happen
before the app starts: importing this module does it.
"""

from __future__ import annotations

import numpy as np
from textual.widget import Widget
from textual_image.renderable import Image as AutoRenderable
from textual_image.renderable.halfcell import Image as HalfcellRenderable
from textual_image.renderable.unicode import Image as UnicodeRenderable

from rigkit.tui.widgets import PixelView, stretch

HAS_GRAPHICS = AutoRenderable not in (HalfcellRenderable, UnicodeRenderable)
"""Whether textual-image found a graphics protocol in this terminal."""


PREVIEW_FRACTION = 1 / 3
"""The share of each side of a frame the preview shows, around its centre."""


def central(image: np.ndarray, fraction: float = PREVIEW_FRACTION) -> np.ndarray:
    """The middle ``fraction`` of ``image`` along each side. A whole frame in the ~36
    columns an 80x24 terminal leaves is some 30 px per cell, which shows texture as
    noise; its middle third is a few px per cell, where the operator sees the scene."""
    height, width = image.shape[:2]
    h, w = max(1, round(height * fraction)), max(1, round(width * fraction))
    top, left = (height - h) // 2, (width - w) // 2
    return image[top : top + h, left : left + w]


def preview_widget(image: np.ndarray, graphics: bool = True) -> Widget:
    """A widget showing ``image`` ((H, W) grey or (H, W, 3) RGB, values 0-255)."""
    pixels = stretch(image) if image.ndim == 2 else np.clip(image, 0, 255).astype(np.uint8)
    if graphics and HAS_GRAPHICS:
        from PIL import Image as PILImage
        from textual_image.widget import Image

        return Image(PILImage.fromarray(pixels))
    return PixelView(pixels)
