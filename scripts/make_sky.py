#!/usr/bin/env python3
"""Writes scenes/sky.hdr: a small equirectangular sky (Radiance RGBE, 128 x 64) for the
environment-light scene and its Mitsuba twin. Blue overhead, white at the horizon, a
brown ground below it and a small bright sun, placed as Mitsuba 3's envmap places a map:
+Y up, row j at theta = pi j / (rows - 1), column i at phi = 2 pi (i + 1/2) / width, the
direction (sin phi sin theta, cos theta, -cos phi sin theta).

Usage: python3 scripts/make_sky.py [OUT.hdr]
"""
import math
import sys

W, H = 128, 64
SUN_DIR = (0.45, 0.75, 0.48)  # toward the sun (normalised below)
SUN_RADIANCE = (60.0, 55.0, 45.0)


def rgbe(r, g, b):
    m = max(r, g, b)
    if m < 1e-32:
        return (0, 0, 0, 0)
    mant, exp = math.frexp(m)
    scale = mant * 256.0 / m
    return (int(r * scale), int(g * scale), int(b * scale), exp + 128)


def radiance(i, j):
    theta = math.pi * j / (H - 1)
    phi = 2 * math.pi * (i + 0.5) / W
    d = (math.sin(phi) * math.sin(theta), math.cos(theta), -math.cos(phi) * math.sin(theta))
    n = math.sqrt(sum(c * c for c in SUN_DIR))
    s = [c / n for c in SUN_DIR]
    if d[1] >= 0:
        t = d[1] ** 0.5
        sky = [0.9 * (1 - t) + 0.25 * t, 0.95 * (1 - t) + 0.45 * t, 1.0 * (1 - t) + 0.9 * t]
    else:
        sky = [0.3, 0.22, 0.15]
    if sum(a * b for a, b in zip(d, s)) > math.cos(math.radians(6.0)):
        sky = list(SUN_RADIANCE)
    return sky


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "scenes/sky.hdr"
    data = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
    data += f"-Y {H} +X {W}\n".encode()
    for j in range(H):
        px = [rgbe(*radiance(i, j)) for i in range(W)]
        # New-style run-length scanline with literal runs only (every reader takes it).
        data += bytes([2, 2, W >> 8, W & 255])
        for c in range(4):
            comp = [p[c] for p in px]
            for k in range(0, W, 128):
                chunk = comp[k:k + 128]
                data += bytes([len(chunk)]) + bytes(chunk)
    with open(out, "wb") as f:
        f.write(data)
    print(f"wrote {out}: {W}x{H}")


if __name__ == "__main__":
    main()
