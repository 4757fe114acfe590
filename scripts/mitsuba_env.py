#!/usr/bin/env python3
"""Mitsuba 3 twin of the environment light: a smooth diffuse sphere and a mirror sphere on
a floor, lit only by an equirectangular map (scenes/sky.hdr: a blue sky, a white horizon
and a small sun) turned by 30 degrees about Y, rendered by lancer's CPU renderer and by
Mitsuba 3 (scalar_rgb, its `envmap` emitter with the same map and rotation). Checks the
map's placement, its importance sampling and the multiple importance sampling with the
diffuse bounce against an independent renderer, in region means.

The script writes the scene's files (sphere.obj with normals, floor.obj, env.toml) into
--out, renders both, and compares the images in 8x8-pixel blocks (linear RGB). With
--report it writes a results page.

    pip install mitsuba        # Mitsuba 3, with drjit
    python3 scripts/mitsuba_env.py                       # 160x80, 256 spp
    python3 scripts/mitsuba_env.py --report docs/src/results/2026-12-03-mitsuba-env.md

Helpers come from mitsuba_cornell.py and mitsuba_smooth.py beside it.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mitsuba_cornell as mc  # noqa: E402
import mitsuba_smooth as ms  # noqa: E402

MAP = mc.ROOT / "scenes" / "sky.hdr"
TURN = 30.0
MAX_BOUNCES = 3
CAMERA = {"position": [0.0, 1.2, 5.0], "look_at": [0.0, 0.6, 0.0], "fov": 35.0}
SPHERES = [  # (centre, radius, lancer material, Mitsuba BSDF)
    ([-0.75, 0.6, 0.0], 0.6, "white", {"type": "diffuse",
                                       "reflectance": {"type": "rgb", "value": [0.8, 0.8, 0.8]}}),
    ([0.75, 0.6, 0.0], 0.6, "mirror", {"type": "conductor", "material": "none"}),
]


def lancer_scene(size, spp):
    rest = """[materials.white]
type = "diffuse"
albedo = [0.8, 0.8, 0.8]
[materials.mirror]
type = "mirror"
"""
    return ms.lancer_spheres(size, spp, MAX_BOUNCES, CAMERA, SPHERES, rest + sky_toml())


def sky_toml():
    """The lancer scene's [environment]: the map turned as Mitsuba's envmap is."""
    return f"""
[environment]
map = "{MAP}"
rotate = [0.0, {TURN}, 0.0]
"""


def mitsuba_scene(mi, out, size, spp, camera, spheres):
    d = ms.mitsuba_spheres(mi, out, size, spp, MAX_BOUNCES, camera, spheres)
    d["sky"] = {"type": "envmap", "filename": str(MAP),
                "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], TURN)}
    return mi.load_dict(d)


def run(doc, out, toml_name, lancer_text, camera, spheres, title, intro, script):
    """Writes the spheres' scene files into --out, renders lancer's scene `lancer_text`
    (a function of size and spp) and its Mitsuba twin under the sky map, and compares."""
    a = ms.arguments(doc.split("\n\n")[0], out)
    mi = mc.load_mitsuba()
    mc.ensure_lancer(a.lancer)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "sphere.obj").write_text(ms.sphere_obj(32))
    (a.out / "floor.obj").write_text(ms.FLOOR_OBJ)
    scene_path = a.out / toml_name
    size = (a.width, a.height)
    scene_path.write_text(lancer_text(size, a.spp))
    ms.twin(a, mi, scene_path, mitsuba_scene(mi, a.out, size, a.spp, camera, spheres), title,
            intro, script)


def main():
    intro = (
        "lancer's environment light against [Mitsuba 3](https://www.mitsuba-renderer.org/): "
        "a smooth diffuse sphere (32 segments, OBJ `vn`) and a mirror sphere on a floor, lit "
        f"only by `scenes/sky.hdr` turned {TURN:g}° about Y (Mitsuba's `envmap` with the "
        f"same `to_world`), path tracing with {MAX_BOUNCES} bounces (Mitsuba `max_depth` "
        f"{mc.max_depth(MAX_BOUNCES)}, no Russian roulette)")
    run(__doc__, "mitsuba-env", "env.toml", lancer_scene, CAMERA, SPHERES, "environment map",
        intro, "mitsuba_env.py")


if __name__ == "__main__":
    main()
