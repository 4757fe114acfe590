#!/usr/bin/env python3
"""Mitsuba 3 twin of glTF's metallic-roughness: three gold metal spheres (`principled`,
metallic 1, roughness 0.2, 0.5 and 0.8) on a floor, lit only by scenes/sky.hdr turned by
30 degrees about Y, rendered by lancer's CPU renderer and by Mitsuba 3 (scalar_rgb, its
`principled` BSDF with metallic 1 and spec_tint 0, whose metal lobe is glTF's: GGX with
Schlick's Fresnel of the base colour; Mitsuba's masking is the separable Smith form,
lancer's the height-correlated one, which differ only near grazing angles). Checks the
microfacet lobe, its visible-normal sampling and its multiple importance sampling with
the environment against an independent renderer, in region means.

Dielectric principled surfaces are not twinned: Mitsuba's `principled` gives them Disney's
diffuse lobe (with its retro-reflection), glTF a Lambert base under the specular Fresnel;
the BRDFs differ by 4-10 % at the same angles.

    pip install mitsuba        # Mitsuba 3, with drjit
    python3 scripts/mitsuba_principled.py                       # 160x80, 256 spp
    python3 scripts/mitsuba_principled.py --report docs/src/results/2026-12-03-mitsuba-principled.md

Helpers come from mitsuba_cornell.py, mitsuba_smooth.py and mitsuba_env.py beside it.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mitsuba_cornell as mc  # noqa: E402
import mitsuba_env as me  # noqa: E402
import mitsuba_smooth as ms  # noqa: E402

MAX_BOUNCES = me.MAX_BOUNCES
GOLD = [1.0, 0.78, 0.34]
ROUGHNESS = [0.2, 0.5, 0.8]
CAMERA = {"position": [0.0, 1.2, 5.0], "look_at": [0.0, 0.5, 0.0], "fov": 35.0}
SPHERES = [  # (centre, radius, lancer material, Mitsuba BSDF)
    ([-1.15 + 1.15 * k, 0.5, 0.0], 0.5, f"gold{k}",
     {"type": "principled", "base_color": {"type": "rgb", "value": GOLD},
      "metallic": 1.0, "roughness": r, "spec_tint": 0.0})
    for k, r in enumerate(ROUGHNESS)
]


def lancer_scene(size, spp):
    rest = "".join(
        f'[materials.gold{k}]\ntype = "principled"\nbase_color = {GOLD}\nmetallic = 1.0\n'
        f"roughness = {r}\n" for k, r in enumerate(ROUGHNESS))
    return ms.lancer_spheres(size, spp, MAX_BOUNCES, CAMERA, SPHERES, rest + me.sky_toml())


def main():
    intro = (
        "lancer's glTF metallic-roughness (`type = \"principled\"`) against "
        "[Mitsuba 3](https://www.mitsuba-renderer.org/)'s `principled` BSDF: three gold "
        "metal spheres (32 segments, OBJ `vn`; roughness "
        + ", ".join(f"{r:g}" for r in ROUGHNESS)
        + " from left to right) on a grey diffuse floor, lit only by `scenes/sky.hdr` "
        f"turned {me.TURN:g}° about Y, path tracing with {MAX_BOUNCES} bounces (Mitsuba "
        f"`max_depth` {mc.max_depth(MAX_BOUNCES)}, no Russian roulette). Mitsuba's metal "
        "lobe is glTF's (GGX, Schlick's Fresnel of the base colour) with the separable "
        "Smith masking where lancer has the height-correlated one; dielectric surfaces are "
        "not twinned, since Mitsuba's `principled` gives them Disney's diffuse lobe rather "
        "than glTF's Lambert base")
    me.run(__doc__, "mitsuba-principled", "principled.toml", lancer_scene, CAMERA, SPHERES,
           "glTF metallic-roughness", intro, "mitsuba_principled.py")


if __name__ == "__main__":
    main()
