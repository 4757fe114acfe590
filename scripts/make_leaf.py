#!/usr/bin/env python3
"""Writes scenes/leaf.png: a 64 x 64 RGBA leaf for alpha-mask cut-outs (scenes/cutout.toml).

Inside the leaf's outline (two arcs meeting at a point, a short stalk below) the texels are
opaque (alpha 255), green, lighter along the midrib and the side veins; outside they are
transparent (alpha 0) and take the border's green, so bilinear lookups near the edge stay
green. A material with `alpha_cutoff = 0.5` cuts the card to the leaf's shape.

    python3 scripts/make_leaf.py            # needs Pillow (pip install pillow)
"""

import math
from pathlib import Path

from PIL import Image

OUT = Path(__file__).resolve().parent.parent / "scenes" / "leaf.png"
N = 64


def inside(x, y):
    """(x, y) in [-1, 1]^2, y up: within the blade (|x| under a sine-shaped half width)
    or the stalk."""
    t = (y + 0.8) / 1.75  # 0 at the blade's base, 1 at its tip
    if 0.0 <= t <= 1.0 and abs(x) <= 0.55 * math.sin(math.pi * t) ** 0.8:
        return True
    return -1.0 <= y < -0.8 and abs(x) < 0.05


def colour(x, y):
    t = (y + 0.8) / 1.75
    base = (46, 110 + int(40 * t), 38)
    # The midrib, and side veins leaving it at 45 degrees every 0.3 along the blade.
    vein = abs(x) < 0.04 or (abs((y - abs(x)) % 0.3 - 0.15) < 0.025 and abs(x) < 0.45)
    return (120, 190, 90) if vein else base


def main():
    img = Image.new("RGBA", (N, N))
    for j in range(N):
        for i in range(N):
            x = (i + 0.5) / N * 2 - 1
            y = 1 - (j + 0.5) / N * 2
            r, g, b = colour(x, y)
            img.putpixel((i, j), (r, g, b, 255 if inside(x, y) else 0))
    img.save(OUT, optimize=True)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
