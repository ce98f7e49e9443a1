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


def preview_widget(image: np.ndarray, graphics: bool = True) -> Widget:
    """A widget showing ``image`` ((H, W) grey or (H, W, 3) RGB, values 0-255)."""
    pixels = stretch(image) if image.ndim == 2 else np.clip(image, 0, 255).astype(np.uint8)
    if graphics and HAS_GRAPHICS:
        from PIL import Image as PILImage
        from textual_image.widget import Image

        return Image(PILImage.fromarray(pixels))
    return PixelView(pixels)
