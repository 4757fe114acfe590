#!/usr/bin/env python3
"""Mitsuba 3 twin of alpha masks: three upright cards cut to a leaf by the alpha of
scenes/leaf.png (lancer: `alpha_cutoff = 0.5`, the test inside its traversal; Mitsuba 3:
its `mask` BSDF with the same alpha as `opacity`, under its `volpath` integrator, whose
shadow rays pass the mask's null part: `path`'s see whole quads) on a floor under a
directional light, rendered by lancer's CPU renderer and by Mitsuba 3 (scalar_rgb). Checks that the holes
are where the alpha says — for camera rays, bounces and shadow rays — against an
independent renderer, in region means. leaf.png's alpha is 0 or 1 on every texel, so the
two agree but for the one-texel band along the outline, where lancer cuts at 0.5 and
Mitsuba blends by the interpolated alpha.

The script writes the scene's files (cards.obj with texture coordinates, floor.obj, the
leaf's colour and alpha as separate PNGs for Mitsuba, cutout.toml) into --out, renders
both, and compares the images in 8x8-pixel blocks (linear RGB). With --report it writes a
results page.

    pip install mitsuba pillow     # Mitsuba 3 (with drjit) and Pillow
    python3 scripts/mitsuba_cutout.py                       # 160x80, 256 spp
    python3 scripts/mitsuba_cutout.py --report docs/src/results/2026-12-03-mitsuba-cutout.md

Helpers come from mitsuba_cornell.py and mitsuba_smooth.py beside it.
"""

import math
import sys
from pathlib import Path

from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mitsuba_cornell as mc  # noqa: E402
import mitsuba_smooth as ms  # noqa: E402

LEAF = mc.ROOT / "scenes" / "leaf.png"
MAX_BOUNCES = 2
LIGHT_DIRECTION = [-0.5, -1.0, -0.7]
IRRADIANCE = 3.0
CAMERA = {"position": [0.0, 1.0, 4.0], "look_at": [0.0, 0.5, 0.0], "fov": 30.0}
CARDS = [  # (centre, half width, turn about Y in degrees)
    ([-1.05, 0.55, 0.0], 0.5, 30.0),
    ([0.0, 0.6, -0.3], 0.55, 0.0),
    ([1.05, 0.5, 0.2], 0.45, -25.0),
]


def cards_obj():
    """The cards in world space, each a quad facing +Z turned about Y, u along its width
    and v up (OBJ's convention: the image's top row at v = 1)."""
    lines, faces = [], []
    for k, (c, h, turn) in enumerate(CARDS):
        a = math.radians(turn)
        right = (math.cos(a) * h, 0.0, -math.sin(a) * h)
        for (sx, sy) in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
            p = [c[0] + sx * right[0], c[1] + sy * h, c[2] + sx * right[2]]
            lines.append(f"v {p[0]!r} {p[1]!r} {p[2]!r}")
        base = 4 * k
        faces += [(base + 1, base + 2, base + 3), (base + 1, base + 3, base + 4)]
    lines += [f"vt {u} {v}" for (u, v) in [(0, 0), (1, 0), (1, 1), (0, 1)]]
    lines += [f"f {a}/{(a - 1) % 4 + 1} {b}/{(b - 1) % 4 + 1} {c}/{(c - 1) % 4 + 1}"
              for (a, b, c) in faces]
    return "\n".join(lines) + "\n"


def lancer_scene(size, spp):
    rest = f"""[materials.leaf]
type = "diffuse"
texture = "{LEAF}"
alpha_cutoff = 0.5

[[objects]]
mesh = "cards.obj"
material = "leaf"

[[lights]]
type = "directional"
direction = {LIGHT_DIRECTION}
intensity = {IRRADIANCE}
"""
    return ms.lancer_spheres(size, spp, MAX_BOUNCES, CAMERA, [], rest)


def mitsuba_scene(mi, out, size, spp):
    # Mitsuba reads the colour (sRGB) and the alpha (raw) as two images.
    img = Image.open(LEAF).convert("RGBA")
    img.convert("RGB").save(out / "leaf-rgb.png")
    img.getchannel("A").save(out / "leaf-alpha.png")
    d = ms.mitsuba_spheres(mi, out, size, spp, MAX_BOUNCES, CAMERA, [])
    # Mitsuba's `path` integrator tests shadow rays against the cards' whole quads (its
    # visibility test does not look at BSDFs); `volpath` traces them through `mask`'s
    # null part, as lancer's any-hit traversal skips the cut hits.
    d["integrator"]["type"] = "volpath"
    d["cards"] = {
        "type": "obj", "filename": str(out / "cards.obj"), "face_normals": True,
        "bsdf": {
            "type": "mask",
            "opacity": {"type": "bitmap", "filename": str(out / "leaf-alpha.png"),
                        "raw": True},
            "bsdf": {"type": "twosided", "bsdf": {
                "type": "diffuse",
                "reflectance": {"type": "bitmap", "filename": str(out / "leaf-rgb.png")}}},
        },
    }
    d["light"] = {"type": "directional", "direction": LIGHT_DIRECTION,
                  "irradiance": {"type": "rgb", "value": IRRADIANCE}}
    return mi.load_dict(d)


def main():
    a = ms.arguments(__doc__.split("\n\n")[0], "mitsuba-cutout")
    mi = mc.load_mitsuba()
    mc.ensure_lancer(a.lancer)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "cards.obj").write_text(cards_obj())
    (a.out / "floor.obj").write_text(ms.FLOOR_OBJ)
    scene_path = a.out / "cutout.toml"
    size = (a.width, a.height)
    scene_path.write_text(lancer_scene(size, a.spp))
    intro = (
        "lancer's alpha masks against [Mitsuba 3](https://www.mitsuba-renderer.org/): three "
        "upright cards textured and cut by `scenes/leaf.png` (lancer: `alpha_cutoff = 0.5`, "
        "tested inside the traversal; Mitsuba: its `mask` BSDF with the image's alpha as "
        "`opacity`, and its `volpath` integrator: `path` lets no shadow ray through a mask) on a "
        "floor under a directional light, path tracing with "
        f"{MAX_BOUNCES} bounces (Mitsuba `max_depth` {mc.max_depth(MAX_BOUNCES)}, no "
        "Russian roulette). The alpha is 0 or 1 on every texel: the renderers differ only "
        "along the one-texel band of the outline, where lancer cuts at 0.5 and Mitsuba "
        "blends by the interpolated alpha")
    ms.twin(a, mi, scene_path, mitsuba_scene(mi, a.out, size, a.spp), "alpha masks", intro,
            "mitsuba_cutout.py")


if __name__ == "__main__":
    main()
