#!/usr/bin/env python3
"""Mitsuba 3 twin of smooth surfaces: a diffuse and a mirror sphere of 16 segments with
vertex normals (OBJ `vn`) on a flat floor under a directional light, rendered by lancer's
CPU renderer and by Mitsuba 3 (scalar_rgb), which interpolates the same vertex normals.
Checks lancer's shading normals (interpolation, the cosine to the light, mirror reflection
about the shading normal) against an independent renderer, in region means.

The script writes the scene's files (sphere.obj with normals, floor.obj, smooth.toml) into
--out, renders both, and compares the images in 8x8-pixel blocks (linear RGB). With
--report it writes a results page.

    pip install mitsuba        # Mitsuba 3, with drjit
    python3 scripts/mitsuba_smooth.py                       # 160x80, 256 spp
    python3 scripts/mitsuba_smooth.py --report docs/src/results/2026-12-03-mitsuba-smooth.md

Helpers (Mitsuba set-up, pixel access, statistics, images, machine) come from
mitsuba_cornell.py beside it.
"""

import argparse
import datetime
import math
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mitsuba_cornell as mc  # noqa: E402

SEGMENTS = 16
BLOCK = 8
MAX_BOUNCES = 2
LIGHT_DIRECTION = [-0.4, -1.0, -0.5]
IRRADIANCE = 3.0
CAMERA = {"position": [0.0, 1.4, 5.0], "look_at": [0.0, 0.5, 0.0], "fov": 30.0}
SPHERES = [  # (centre, radius, lancer material, Mitsuba BSDF)
    ([-0.75, 0.6, 0.0], 0.6, "red", {"type": "diffuse",
                                     "reflectance": {"type": "rgb", "value": [0.8, 0.2, 0.1]}}),
    ([0.75, 0.6, 0.0], 0.6, "mirror", {"type": "conductor", "material": "none"}),
]


def sphere_obj(segments):
    """A unit UV sphere as lancer's built-in one (segments around Y, segments/2 rings, the
    poles' degenerate halves left out), each vertex's normal its position."""
    ns, nr = max(segments, 3), max(segments // 2, 2)

    def point(i, j):
        phi, theta = 2 * math.pi * i / ns, math.pi * j / nr
        return (math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi))

    verts, faces = [], []

    def vid(i, j):
        verts.append(point(i, j))
        return len(verts)

    for j in range(nr):
        for i in range(ns):
            a, b, c, d = (i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)
            if j != 0:
                faces.append((vid(*a), vid(*b), vid(*d)))
            if j != nr - 1:
                faces.append((vid(*b), vid(*c), vid(*d)))
    lines = [f"v {x!r} {y!r} {z!r}" for (x, y, z) in verts]
    lines += [f"vn {x!r} {y!r} {z!r}" for (x, y, z) in verts]
    lines += [f"f {a}//{a} {b}//{b} {c}//{c}" for (a, b, c) in faces]
    return "\n".join(lines) + "\n"


FLOOR_OBJ = "v -5 0 5\nv 5 0 5\nv 5 0 -5\nv -5 0 -5\nf 1 2 3\nf 1 3 4\n"


def lancer_spheres(size, spp, max_bounces, camera, spheres, rest):
    """A lancer scene of `spheres` (centre, radius, material name, Mitsuba BSDF) on the
    floor, seen from `camera`, path traced; `rest` adds its materials, lights and
    environment (the floor's grey is here)."""
    w, h = size
    objects = "".join(
        f'\n[[objects]]\nmesh = "sphere.obj"\nmaterial = "{m}"\nscale = {r}\n'
        f"translate = {c}\n" for (c, r, m, _) in spheres)
    return f"""[camera]
position = {camera["position"]}
look_at = {camera["look_at"]}
fov = {camera["fov"]}
width = {w}
height = {h}

[render]
integrator = "path"
max_bounces = {max_bounces}
spp = {spp}

[materials.floor]
type = "diffuse"
albedo = [0.6, 0.6, 0.6]
{rest}
[[objects]]
mesh = "floor.obj"
material = "floor"
{objects}"""


def lancer_scene(size, spp):
    rest = f"""[materials.red]
type = "diffuse"
albedo = [0.8, 0.2, 0.1]
[materials.mirror]
type = "mirror"

[[lights]]
type = "directional"
direction = {LIGHT_DIRECTION}
intensity = {IRRADIANCE}
"""
    return lancer_spheres(size, spp, MAX_BOUNCES, CAMERA, SPHERES, rest)


def mitsuba_spheres(mi, out, size, spp, max_bounces, camera, spheres):
    """The Mitsuba twin of lancer_spheres, without its lights: a dict to add them to."""
    w, h = size
    depth = mc.max_depth(max_bounces)
    two_sided = lambda bsdf: {"type": "twosided", "bsdf": bsdf}  # noqa: E731
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": depth, "rr_depth": depth},
        "sensor": {
            "type": "perspective", "fov_axis": "y", "fov": camera["fov"],
            "to_world": mi.ScalarTransform4f().look_at(
                origin=camera["position"], target=camera["look_at"], up=[0, 1, 0]),
            "near_clip": 1e-3, "far_clip": 1e7,
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"},
                     "pixel_format": "rgb", "component_format": "float32"},
        },
        "floor": {"type": "obj", "filename": str(out / "floor.obj"), "face_normals": True,
                  "bsdf": two_sided({"type": "diffuse",
                                     "reflectance": {"type": "rgb", "value": 0.6}})},
    }
    for k, (c, r, _, bsdf) in enumerate(spheres):
        d[f"sphere{k}"] = {
            "type": "obj", "filename": str(out / "sphere.obj"), "face_normals": False,
            "to_world": mi.ScalarTransform4f().translate(c).scale(r),
            "bsdf": two_sided(bsdf) if bsdf["type"] == "diffuse" else bsdf,
        }
    return d


def mitsuba_scene(mi, out, size, spp):
    d = mitsuba_spheres(mi, out, size, spp, MAX_BOUNCES, CAMERA, SPHERES)
    d["light"] = {"type": "directional", "direction": LIGHT_DIRECTION,
                  "irradiance": {"type": "rgb", "value": IRRADIANCE}}
    return mi.load_dict(d)


def block_report(stats_a, stats_b):
    """Relative differences of the 8x8 block means (RGB summed) where Mitsuba's block is
    not dark, and how many blocks that is."""
    out = []
    for k, (ba, bb) in enumerate(zip(stats_a, stats_b)):
        if bb > 0.02:
            out.append(((ba - bb) / bb, k))
    return out


def twin(a, mi, scene_path, mitsuba, title, intro, script):
    """Renders the lancer scene at `scene_path` (CPU) and the Mitsuba scene `mitsuba`,
    compares them in 8x8-pixel blocks, prints the tables and, with --report, writes a
    results page titled `title` (`intro` says what the twin is, `script` what made it)."""
    exr = a.out / "lancer.exr"
    cmd = [mc.rel(a.lancer), "render", mc.rel(scene_path), "-o", mc.rel(exr), "--device", "cpu"]
    start = time.perf_counter()
    subprocess.run(cmd, cwd=mc.ROOT, check=True)
    lancer_s = time.perf_counter() - start
    mitsuba_bmp, mitsuba_s = mc.render_mitsuba(mi, mitsuba, a.spp, 0)
    lancer_bmp = mi.Bitmap(str(exr))
    stats = mc.compare(mi, lancer_bmp, mitsuba_bmp)
    images = mc.write_images(mi, a.out, lancer_bmp, mitsuba_bmp, stats)
    w, h, la = mc.pixels(mi, lancer_bmp)
    _, _, lb = mc.pixels(mi, mitsuba_bmp)
    # Each pixel's R + G + B in the red channel: block_means of that, red only.
    summed = lambda v: [x for i in range(0, len(v), 3) for x in (sum(v[i:i + 3]), 0.0, 0.0)]  # noqa: E731
    ba = mc.block_means(w, h, summed(la), BLOCK)[0::3]
    bb = mc.block_means(w, h, summed(lb), BLOCK)[0::3]
    blocks = block_report(ba, bb)
    rel = [x for x, _ in blocks]
    mean_abs = math.fsum(abs(x) for x in rel) / len(rel)
    within = sum(abs(x) <= 0.02 for x in rel)
    worst, at = max(blocks, key=lambda b: abs(b[0]))
    bx, by = BLOCK * (at % (w // BLOCK)), BLOCK * (at // (w // BLOCK))
    lines = [
        "| image (linear RGB) | mean R, G, B |", "|---|---|",
        "| lancer | " + ", ".join(f"{x:.4f}" for x in stats["lancer_mean"]) + " |",
        "| Mitsuba 3 | " + ", ".join(f"{x:.4f}" for x in stats["mitsuba_mean"]) + " |",
        "| lancer ÷ Mitsuba − 1 | " + ", ".join(f"{100 * x:+.2f} %" for x in stats["rel_diff"])
        + " |",
        "",
        f"{BLOCK}×{BLOCK}-pixel blocks (RGB summed) brighter than 0.02 in Mitsuba's image: "
        f"{len(rel)}; mean |lancer ÷ Mitsuba − 1| = {100 * mean_abs:.2f} %; within 2 %: "
        f"{within} of {len(rel)}; largest {100 * worst:+.2f} % (pixels x {bx}–{bx + BLOCK - 1}, "
        f"y {by}–{by + BLOCK - 1}: lancer {ba[at]:.4f}, Mitsuba {bb[at]:.4f}).",
        "",
        f"Seconds: lancer {lancer_s:.2f} (wall, CPU), Mitsuba {mitsuba_s:.2f} (mi.render).",
    ]
    print("\n".join(lines))
    if a.report:
        a.report.parent.mkdir(parents=True, exist_ok=True)
        stem = a.report.with_suffix("")
        shown = []
        for img in images:
            target = Path(f"{stem}-{img.name}")
            target.write_bytes(img.read_bytes())
            shown.append(f"![{img.stem}]({target.name})")
        now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        a.report.write_text("\n".join([
            f"# Mitsuba 3 twin: {title}", "",
            intro + f", made by `scripts/{script}`.", "",
            f"- Machine: {mc.machine()}", f"- Date: {now}", f"- Commit: `{mc.git_commit()}`",
            f"- Mitsuba {mi.__version__}, variant `{mc.VARIANT}`; {w}×{h} pixels, {a.spp} spp",
            "", "Commands:", "", "```sh",
            # The command as it was given (its options included).
            " ".join(["python3", f"scripts/{script}", *sys.argv[1:]]),
            "# runs:", " ".join(cmd), "```", "", *lines, "",
            "lancer, Mitsuba 3, and the difference (red: lancer brighter, blue: Mitsuba "
            f"brighter, {mc.DIFF_SCALE:g}× the RGB mean):", "", " ".join(shown), "",
        ]))
        print(f"wrote {mc.rel(a.report)}")


def arguments(description, out):
    """The twins' command line: image size, samples, lancer's binary, the folder the
    scene's files go to, and the results page to write."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--width", type=int, default=160)
    p.add_argument("--height", type=int, default=80)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--lancer", type=Path, default=mc.DEFAULT_LANCER)
    p.add_argument("--out", type=Path, default=mc.ROOT / "target" / out)
    p.add_argument("--report", type=Path)
    return p.parse_args()


def main():
    a = arguments(__doc__.split("\n\n")[0], "mitsuba-smooth")
    mi = mc.load_mitsuba()
    mc.ensure_lancer(a.lancer)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "sphere.obj").write_text(sphere_obj(SEGMENTS))
    (a.out / "floor.obj").write_text(FLOOR_OBJ)
    scene_path = a.out / "smooth.toml"
    size = (a.width, a.height)
    scene_path.write_text(lancer_scene(size, a.spp))
    intro = (
        "lancer's shading normals against [Mitsuba 3](https://www.mitsuba-renderer.org/): "
        f"a diffuse and a mirror sphere of {SEGMENTS} segments with vertex normals (OBJ "
        "`vn`) on a flat floor under a directional light, path tracing with "
        f"{MAX_BOUNCES} bounces (Mitsuba `max_depth` {mc.max_depth(MAX_BOUNCES)}, no "
        "Russian roulette)")
    twin(a, mi, scene_path, mitsuba_scene(mi, a.out, size, a.spp), "smooth spheres", intro,
         "mitsuba_smooth.py")


if __name__ == "__main__":
    main()
