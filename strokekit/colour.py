"""sRGB transfer functions (IEC 61966-2-1). Scene colours (glTF baseColorFactor, OBJ Kd as Blender
reads it) are linear; 8-bit images and SVG colours are sRGB-encoded."""

from __future__ import annotations

import numpy as np


def srgb_encode(linear) -> np.ndarray:
    """Linear values in [0, 1] (any shape) -> sRGB-encoded values in [0, 1]."""
    x = np.clip(np.asarray(linear, float), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_decode(encoded) -> np.ndarray:
    """sRGB-encoded values in [0, 1] (any shape) -> linear values in [0, 1]."""
    x = np.clip(np.asarray(encoded, float), 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, np.power((x + 0.055) / 1.055, 2.4))
