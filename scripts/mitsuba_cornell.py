#!/usr/bin/env python3
"""Mitsuba 3 twin of lancer's Cornell box: the same scene rendered by an independent
renderer, to check lancer's CPU path tracer (mean brightness per channel) and to time it.

The twin is built from lancer's own files: scenes/cornell.toml (camera, size, bounces,
spp) and the OBJ/MTL it names (geometry, diffuse Kd, emissive Ke). The OBJ's triangles are
grouped by material and written as one small OBJ per material into a temporary folder,
which Mitsuba loads with the matching BSDF (and an area emitter for the light).

Both renderers run on the CPU: lancer as `target/release/lancer render ... --device cpu`
(a subprocess; rayon on all cores) and Mitsuba through `mi.render` in the `scalar_rgb`
variant (its own thread pool on all cores). Each gets an untimed warm-up at 1 spp first.
The images are compared in linear RGB (lancer's EXR against Mitsuba's film) and written
as PNGs, with a signed difference, into --out.

Requires Python 3.11+ (tomllib) and Mitsuba 3 (this script installs nothing):

    pip install mitsuba        # brings drjit; no numpy needed

Run from anywhere (paths are relative to the repository):

    python3 scripts/mitsuba_cornell.py                        # 256x256, 64 spp, 1 run
    python3 scripts/mitsuba_cornell.py --spp 16 --size 128    # a quick check
    python3 scripts/mitsuba_cornell.py --runs 5 --report docs/src/results/mitsuba-cornell.md

The lancer binary is built (`cargo build --release`) only when the default
target/release/lancer is missing.
"""

import argparse
import datetime
import math
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "cornell.toml"
DEFAULT_LANCER = ROOT / "target" / "release" / "lancer"
DEFAULT_OUT = ROOT / "target" / "mitsuba-cornell"
VARIANT = "scalar_rgb"
# The difference image shows (lancer - mitsuba) averaged over RGB, times this: red where
# lancer is brighter, blue where Mitsuba is.
DIFF_SCALE = 4.0
# Block size (pixels) of the block-mean RMSE, which averages most of the noise away and
# keeps structural differences (a shifted camera, a missing bounce).
BLOCK = 8
# lancer's summary line: "256x256 64/64 spp -> OUT (cpu (2 threads), 3.21 s)".
SUMMARY = re.compile(
    r"spp -> .*? \((?P<device>[^()]*(?:\([^()]*\))?), (?P<seconds>[0-9.]+) s\)")


def load_mitsuba():
    """Imports Mitsuba 3 and selects the scalar_rgb variant, or exits saying how to get it."""
    try:
        import mitsuba as mi
    except ImportError:
        sys.exit("mitsuba_cornell: Mitsuba 3 is not installed: pip install mitsuba")
    mi.set_variant(VARIANT)
    return mi


def mitsuba_threads():
    """The size of the thread pool mi.render uses in the scalar variants (Dr.Jit's; all
    logical CPUs unless changed)."""
    import drjit as dr  # installed with mitsuba

    return dr.thread_count()


def rel(path):
    """`path` relative to the repository when inside it (for printing), else absolute."""
    path = Path(path).resolve()
    try:
        return str(path.relative_to(ROOT))
    except ValueError:
        return str(path)


def read_scene(path):
    """The settings of a lancer TOML scene that the twin reproduces, checking that the
    scene uses nothing else (one mesh, no transforms, no point or directional lights)."""
    with open(path, "rb") as f:
        s = tomllib.load(f)
    cam, render = s["camera"], s.get("render", {})
    objects = s.get("objects", [])
    if s.get("lights") or s.get("materials") or len(objects) != 1:
        sys.exit(f"{path}: the twin handles one mesh with its MTL materials and no lights")
    obj = objects[0]
    if set(obj) != {"mesh"}:
        sys.exit(f"{path}: the twin handles an untransformed mesh with its MTL materials")
    if render.get("integrator", "path") != "path" or any(render.get("background", [0] * 3)):
        sys.exit(f"{path}: the twin handles the path integrator on a black background")
    return {
        "position": cam["position"],
        "look_at": cam["look_at"],
        "up": cam.get("up", [0.0, 1.0, 0.0]),  # lancer's defaults (scene/file.rs)
        "fov": cam.get("fov", 40.0),
        "width": cam.get("width", 512),
        "height": cam.get("height", 512),
        "max_bounces": render.get("max_bounces", 4),
        "spp": render.get("spp", 16),
        "mesh": path.parent / obj["mesh"],
    }


def read_mtl(path):
    """MTL materials as {name: {"Kd": [r, g, b], "Ke": [r, g, b]}} (Kd defaulting to 0.7
    and clamped to 1, Ke to 0, as lancer reads them)."""
    materials, current = {}, None
    for line in path.read_text().splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] == "newmtl":
            current = materials[words[1]] = {"Kd": [0.7] * 3, "Ke": [0.0] * 3}
        elif words[0] in ("Kd", "Ke") and current is not None:
            current[words[0]] = [float(w) for w in words[1:4]]
    for m in materials.values():
        m["Kd"] = [min(x, 1.0) for x in m["Kd"]]
    return materials


def read_obj(path):
    """An OBJ's triangles grouped by material: (mtllib file, {material: [(a, b, c)]}) with
    each corner an (x, y, z) tuple; polygons are fan-triangulated, as lancer does."""
    positions, groups, mtllib, material = [], {}, None, None
    for line in path.read_text().splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] == "v":
            positions.append(tuple(float(w) for w in words[1:4]))
        elif words[0] == "mtllib":
            mtllib = path.parent / words[1]
        elif words[0] == "usemtl":
            material = words[1]
        elif words[0] == "f":
            # "i", "i/t", "i//n" or "i/t/n"; negative indices count back from the last v.
            idx = [int(w.split("/")[0]) for w in words[1:]]
            corners = [positions[i - 1 if i > 0 else len(positions) + i] for i in idx]
            tris = groups.setdefault(material, [])
            for k in range(1, len(corners) - 1):
                tris.append((corners[0], corners[k], corners[k + 1]))
    return mtllib, groups


def write_group_objs(groups, folder):
    """Writes each material's triangles as its own OBJ in `folder`: {material: path}."""
    paths = {}
    for name, tris in groups.items():
        lines = [f"v {x!r} {y!r} {z!r}" for tri in tris for (x, y, z) in tri]
        lines += [f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}" for i in range(len(tris))]
        paths[name] = Path(folder) / f"{name}.obj"
        paths[name].write_text("\n".join(lines) + "\n")
    return paths


def max_depth(max_bounces):
    """Mitsuba's path `max_depth` for lancer's `max_bounces`.

    lancer (src/render/cpu.rs) loops `for bounce in 0..=max_bounces`: the camera ray's hit
    is bounce 0, every diffuse hit adds next-event estimation (a shadow ray to the light)
    and, unless it is the last bounce, continues with a cosine-sampled ray. The longest
    path is therefore camera -> max_bounces + 1 diffuse vertices -> light: max_bounces + 2
    segments (max_bounces = 0 is direct light only). Mitsuba's `max_depth` counts path
    segments the same way (1: emitters seen directly, 2: direct light), so
    max_depth = max_bounces + 2: 6 for the box's 4 bounces.
    """
    return max_bounces + 2


def scene_dict(mi, scene, materials, obj_paths, size, spp):
    """The Mitsuba scene dictionary of the twin at size x size pixels and `spp` samples."""
    depth = max_depth(scene["max_bounces"])
    d = {
        "type": "scene",
        "integrator": {
            "type": "path",
            "max_depth": depth,
            # lancer has no Russian roulette: start it past the last vertex so that both
            # trace the same paths (roulette is unbiased; only the work would differ).
            "rr_depth": depth,
        },
        "sensor": {
            # A pinhole with lancer's camera basis: look_at(origin, target, up) puts +x
            # (right) on the image's right and up at the top, row 0 at the top, as lancer's
            # CameraFrame does; fov is the full vertical angle in both.
            "type": "perspective",
            "fov_axis": "y",
            "fov": scene["fov"],
            "to_world": mi.ScalarTransform4f().look_at(
                origin=scene["position"], target=scene["look_at"], up=scene["up"]
            ),
            # lancer's camera rays are unbounded; the box (mm) is ~2000 units away.
            "near_clip": 1e-3,
            "far_clip": 1e7,
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {
                # One uniformly jittered sample per pixel per spp, averaged: a box filter
                # of the pixel's own extent (radius 0.5), as lancer's jittered camera rays.
                "type": "hdrfilm",
                "width": size,
                "height": size,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
                "component_format": "float32",
            },
        },
    }
    for name, path in obj_paths.items():
        m = materials[name]
        shape = {"type": "obj", "filename": str(path), "face_normals": True}
        if max(m["Ke"]) > 0:
            # lancer's emissive material emits Ke from its front face (the winding's
            # normal, as Mitsuba's area emitter) and reflects nothing.
            shape["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}}
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": m["Ke"]}}
        else:
            # lancer's diffuse turns the normal toward the ray: two-sided Lambertian.
            shape["bsdf"] = {
                "type": "twosided",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": m["Kd"]}},
            }
        d[f"shape_{name}"] = shape
    return d


def build_mitsuba_scene(mi, scene, size, spp):
    """Parses the scene's OBJ and MTL and loads the twin into Mitsuba."""
    mtllib, groups = read_obj(scene["mesh"])
    materials = read_mtl(mtllib)
    with tempfile.TemporaryDirectory(prefix="mitsuba-cornell-") as folder:
        paths = write_group_objs(groups, folder)
        return mi.load_dict(scene_dict(mi, scene, materials, paths, size, spp))


def render_mitsuba(mi, scene, spp, seed):
    """One timed mi.render: (the image as a Bitmap, seconds)."""
    start = time.perf_counter()
    image = mi.render(scene, spp=spp, seed=seed)
    seconds = time.perf_counter() - start
    return mi.Bitmap(image), seconds


def lancer_command(lancer, out, size, spp):
    """The lancer command line rendering the box at size x size, `spp` samples, on the CPU."""
    return [rel(lancer), "render", rel(SCENE), "-o", rel(out), "--device", "cpu",
            "--spp", str(spp), "--width", str(size), "--height", str(size)]


def run_lancer(cmd):
    """Runs lancer (from the repository root): (wall seconds, its own render seconds, its
    device string such as "cpu (2 threads)")."""
    start = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if p.returncode != 0:
        sys.exit(f"mitsuba_cornell: {shlex.join(cmd)} failed:\n{p.stdout}{p.stderr}")
    m = SUMMARY.search(p.stdout + p.stderr)
    if not m:
        sys.exit(f"mitsuba_cornell: no summary line from lancer:\n{p.stdout}{p.stderr}")
    return wall, float(m["seconds"]), m["device"]


def ensure_lancer(path):
    """Checks that the lancer binary exists, building the default one if it is missing."""
    if path.exists():
        return
    if path.resolve() != DEFAULT_LANCER:
        sys.exit(f"mitsuba_cornell: {path} does not exist")
    print("building lancer: cargo build --release", flush=True)
    subprocess.run(["cargo", "build", "--release"], cwd=ROOT, check=True)


def pixels(mi, bitmap):
    """A Bitmap's linear RGB values as (width, height, flat list r, g, b, r, ... row-major
    from the top)."""
    rgb = bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
    w, h = rgb.size()
    return w, h, list(mi.TensorXf(rgb).array)


def channel_means(values):
    """Mean of each of R, G, B over the image (in double precision)."""
    n = len(values) // 3
    return [math.fsum(values[c::3]) / n for c in range(3)]


def noise_of_mean_difference(a, b):
    """Per channel, the standard error (1 sigma) of mean(a) - mean(b) estimated from the
    per-pixel differences: pixels are independent samples, so it is their standard
    deviation over sqrt(pixel count). Mostly Monte Carlo noise of both images."""
    n = len(a) // 3
    out = []
    for c in range(3):
        d = [x - y for x, y in zip(a[c::3], b[c::3])]
        mean = math.fsum(d) / n
        out.append(math.sqrt(math.fsum((x - mean) ** 2 for x in d) / (n - 1) / n))
    return out


def rmse(a, b):
    """Root mean square difference over every channel of every pixel."""
    return math.sqrt(math.fsum((x - y) ** 2 for x, y in zip(a, b)) / len(a))


def block_means(w, h, values, block):
    """Means of each channel over block x block tiles (the image cropped to whole tiles)."""
    out = []
    for by in range(h // block):
        for bx in range(w // block):
            for c in range(3):
                s = math.fsum(values[3 * ((by * block + y) * w + bx * block + x) + c]
                              for y in range(block) for x in range(block))
                out.append(s / (block * block))
    return out


def compare(mi, lancer_bmp, mitsuba_bmp):
    """Statistics of lancer's image against Mitsuba's (linear RGB)."""
    w, h, a = pixels(mi, lancer_bmp)
    w2, h2, b = pixels(mi, mitsuba_bmp)
    if (w, h) != (w2, h2):
        sys.exit(f"mitsuba_cornell: lancer's image is {w}x{h}, Mitsuba's {w2}x{h2}")
    ma, mb = channel_means(a), channel_means(b)
    return {
        "lancer_mean": ma,
        "mitsuba_mean": mb,
        "rel_diff": [(x - y) / y if y else float("nan") for x, y in zip(ma, mb)],
        "rel_diff_all": (sum(ma) - sum(mb)) / sum(mb),
        "rel_noise": [s / y if y else float("nan")
                      for s, y in zip(noise_of_mean_difference(a, b), mb)],
        "rmse": rmse(a, b),
        "block_rmse": rmse(block_means(w, h, a, BLOCK), block_means(w, h, b, BLOCK)),
        "size": (w, h),
        "diff": [DIFF_SCALE * (sum(a[i:i + 3]) - sum(b[i:i + 3])) / 3
                 for i in range(0, len(a), 3)],
    }


def write_png(mi, bitmap, path):
    """Writes a linear RGB Bitmap as an 8-bit sRGB PNG."""
    srgb = bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True)
    srgb.write(str(path))


def write_images(mi, out, lancer_bmp, mitsuba_bmp, stats):
    """Writes lancer.png, mitsuba.png and diff.png (red: lancer brighter, blue: Mitsuba
    brighter, DIFF_SCALE x the RGB mean difference) into `out`: their paths."""
    w, h = stats["size"]
    diff = []
    for d in stats["diff"]:
        diff += [max(d, 0.0), 0.0, max(-d, 0.0)]
    diff_bmp = mi.Bitmap(mi.TensorXf(diff, shape=(h, w, 3)))
    paths = [out / "lancer.png", out / "mitsuba.png", out / "diff.png"]
    for bmp, path in zip((lancer_bmp, mitsuba_bmp, diff_bmp), paths):
        write_png(mi, bmp, path)
    mitsuba_bmp.write(str(out / "mitsuba.exr"))
    return paths


def tables(timing, devices, stats, spp):
    """The results as Markdown tables (printed, and the report's body): `timing` holds
    each run's seconds, `devices` each renderer's threads."""
    w, h = stats["size"]
    med = {k: statistics.median(v) for k, v in timing.items()}
    runs = {k: " ".join(f"{s:.2f}" for s in v) for k, v in timing.items()}
    size = f"{w}x{h}"
    rows = [
        ("lancer (wall)", devices["lancer"], med["lancer_wall"], runs["lancer_wall"]),
        ("lancer (its own seconds)", devices["lancer"], med["lancer_render"],
         runs["lancer_render"]),
        ("Mitsuba 3 (mi.render)", devices["mitsuba"], med["mitsuba"], runs["mitsuba"]),
    ]
    lines = [
        "| renderer | threads | spp | size | seconds (median) | ratio lancer/Mitsuba | runs (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, device, sec, each in rows:
        lines.append(f"| {name} | {device} | {spp} | {size} | {sec:.2f} | "
                     f"{sec / med['mitsuba']:.2f} | {each} |")
    fmt = lambda v: ", ".join(f"{x:.4f}" for x in v)  # noqa: E731
    lines += [
        "",
        "| image (linear RGB) | mean R, G, B |",
        "|---|---|",
        f"| lancer | {fmt(stats['lancer_mean'])} |",
        f"| Mitsuba 3 | {fmt(stats['mitsuba_mean'])} |",
        "| relative difference (lancer − Mitsuba) / Mitsuba | "
        + ", ".join(f"{100 * x:+.2f} %" for x in stats["rel_diff"])
        + f" (RGB sum {100 * stats['rel_diff_all']:+.2f} %) |",
        "| its noise (1 σ, from the per-pixel differences) | "
        + ", ".join(f"{100 * x:.2f} %" for x in stats["rel_noise"]) + " |",
        f"| RMSE per pixel and channel | {stats['rmse']:.4f} |",
        f"| RMSE of {BLOCK}x{BLOCK}-pixel block means | {stats['block_rmse']:.4f} |",
    ]
    return "\n".join(lines)


def machine():
    """The CPU's model name and logical CPU count, from /proc/cpuinfo."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return f"unknown CPU, {os.cpu_count()} logical CPUs"
    models = re.findall(r"^model name\s*:\s*(.*)$", info, re.M)
    count = len(re.findall(r"^processor\s*:", info, re.M))
    return f"{models[0] if models else 'unknown CPU'}, {count} logical CPUs"


def git_commit():
    """`git rev-parse --short HEAD`, marked when tracked files have uncommitted changes."""
    git = lambda *a: subprocess.run(["git", *a], cwd=ROOT, capture_output=True,  # noqa: E731
                                    text=True).stdout.strip()
    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--untracked-files=no"):
        commit += " (with uncommitted changes)"
    return commit


def write_report(path, body, commands, images, mi_version, depth):
    """Writes the results page `path` (replacing it), the PNGs copied beside it under
    images/ as <page name>-<image>.png."""
    folder = path.parent
    (folder / "images").mkdir(parents=True, exist_ok=True)
    links = []
    for image in images:
        target = folder / "images" / f"{path.stem}-{image.name}"
        shutil.copyfile(image, target)
        links.append(target.relative_to(folder).as_posix())
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    text = f"""# Mitsuba 3 twin: the Cornell box

lancer's CPU path tracer against [Mitsuba 3](https://www.mitsuba-renderer.org/) on the
same scene (`scenes/cornell.toml`), made by `scripts/mitsuba_cornell.py`: images compared
in linear RGB, render times on the same machine.

- Machine: {machine()}
- Date: {now}
- Commit: `{git_commit()}`
- Mitsuba {mi_version}, variant `{VARIANT}`, `path` integrator with `max_depth = {depth}`
  (lancer's `max_bounces` + 2: the longest path, camera to light, in segments) and no
  Russian roulette; `independent` sampler; `hdrfilm` with a `box` filter.

Commands:

```sh
{chr(10).join(commands)}
```

{body}

Seconds: lancer's wall time includes its start, scene load, BVH build and EXR write; its
own seconds (its summary line) and `mi.render` time only the sampling. Mitsuba's scene is
loaded before the clock starts. Each renderer had an untimed 1-spp warm-up; timed runs
alternate lancer and Mitsuba.

| lancer | Mitsuba 3 | difference ×{DIFF_SCALE:g} (red: lancer brighter, blue: Mitsuba brighter) |
|---|---|---|
| ![lancer]({links[0]}) | ![Mitsuba 3]({links[1]}) | ![difference]({links[2]}) |
"""
    path.write_text(text)


def parse_args(scene):
    """Command-line options (defaults from the scene file)."""
    p = argparse.ArgumentParser(
        description="Render lancer's Cornell box with lancer (CPU) and Mitsuba 3, compare "
        "the images and time both.")
    p.add_argument("--spp", type=int, default=scene["spp"],
                   help=f"samples per pixel (default: the scene's, {scene['spp']})")
    p.add_argument("--size", type=int, default=scene["width"],
                   help=f"image width and height (default: the scene's, {scene['width']})")
    p.add_argument("--lancer", type=Path, default=DEFAULT_LANCER,
                   help=f"lancer binary (default: {rel(DEFAULT_LANCER)}, built if missing)")
    p.add_argument("--runs", type=int, default=1,
                   help="timed renders of each, alternating (default 1); the median is reported")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT,
                   help=f"output folder for images (default: {rel(DEFAULT_OUT)})")
    p.add_argument("--report", type=Path,
                   help="write a Markdown results page here (replacing it), images beside it "
                   "under images/")
    args = p.parse_args()
    if args.spp < 1 or args.size < 1 or args.runs < 1:
        p.error("--spp, --size and --runs must be at least 1")
    if scene["width"] != scene["height"]:
        p.error("the scene's image is not square: --size would change its aspect ratio")
    return args


def main():
    """Renders with both, times them, compares the images and prints (or writes) results."""
    scene = read_scene(SCENE)
    args = parse_args(scene)
    mi = load_mitsuba()
    ensure_lancer(args.lancer)
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    lancer_exr = out / "lancer.exr"
    cmd = lancer_command(args.lancer, lancer_exr, args.size, args.spp)

    mi_scene = build_mitsuba_scene(mi, scene, args.size, args.spp)
    threads = mitsuba_threads()
    print(f"lancer:  {shlex.join(cmd)}")
    print(f"Mitsuba: {mi.__version__} {VARIANT}, {threads} threads, "
          f"max_depth {max_depth(scene['max_bounces'])}", flush=True)

    # Untimed warm-ups at 1 spp: binary and files in the page cache, Mitsuba's thread pool.
    run_lancer(lancer_command(args.lancer, out / "warm-up.exr", args.size, 1))
    (out / "warm-up.exr").unlink()
    render_mitsuba(mi, mi_scene, 1, seed=0)

    timing = {"lancer_wall": [], "lancer_render": [], "mitsuba": []}
    for run in range(args.runs):
        wall, own, device = run_lancer(cmd)
        mitsuba_bmp, seconds = render_mitsuba(mi, mi_scene, args.spp, seed=run)
        timing["lancer_wall"].append(wall)
        timing["lancer_render"].append(own)
        timing["mitsuba"].append(seconds)
        print(f"run {run + 1}/{args.runs}: lancer {wall:.2f} s wall ({own:.2f} s own), "
              f"Mitsuba {seconds:.2f} s", flush=True)
    devices = {"lancer": device, "mitsuba": f"{threads} threads"}

    lancer_bmp = mi.Bitmap(str(lancer_exr))
    stats = compare(mi, lancer_bmp, mitsuba_bmp)
    images = write_images(mi, out, lancer_bmp, mitsuba_bmp, stats)
    body = tables(timing, devices, stats, args.spp)
    print()
    print(body)
    print()
    print("images: " + ", ".join(rel(p) for p in images))

    if args.report:
        commands = [
            shlex.join(["python3", rel(__file__), *sys.argv[1:]]),
            "# runs, from the repository root, per timed run:",
            shlex.join(cmd),
        ]
        write_report(args.report.resolve(), body, commands, images, mi.__version__,
                     max_depth(scene["max_bounces"]))
        print(f"report: {rel(args.report)}")


if __name__ == "__main__":
    main()
