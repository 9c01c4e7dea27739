"""The overlay's labels (foldbot.perception.overlay): readable text whose outline hugs it."""

import numpy as np

from foldbot.perception.overlay import _text


def test_a_labels_outline_stays_on_its_text():
    img = np.full((40, 240, 3), 128, np.uint8)
    _text(img, "near_right 0.97", (10, 25), (255, 255, 0))
    coloured = np.flatnonzero((img[..., 0] > 200).any(axis=0))
    dark = np.flatnonzero((img.max(axis=2) < 60).any(axis=0))
    assert coloured.size and dark.size
    # The black outline surrounds the text by a pixel; it does not drift past its end.
    assert dark.min() >= coloured.min() - 2
    assert dark.max() <= coloured.max() + 2
