#!/usr/bin/env python3
"""Writes scenes/panel.glb: a small glTF 2.0 asset that uses what models such as Khronos'
DamagedHelmet use — a metallic-roughness material with base colour, metallic-roughness,
emissive and normal textures — on a UV sphere with normals and texture coordinates.

The textures (64 x 32 PNGs in the GLB's binary chunk):
- base colour: a checker of warm grey and dark blue;
- metallic-roughness: metal (blue 255) on the upper half, dielectric below; roughness
  (green) rising from 0.15 to 1 around the sphere;
- emissive: black, but for a band of lit panels just above the equator (emissive factor
  [4, 3, 1.5]);
- normal: round bumps, a height field's slopes in tangent space (green up).

    python3 scripts/make_panel.py            # needs Pillow (pip install pillow)
"""

import io
import json
import math
import struct
from pathlib import Path

from PIL import Image

OUT = Path(__file__).resolve().parent.parent / "scenes" / "panel.glb"
W, H = 64, 32
SEGMENTS, RINGS = 48, 24


def png(f):
    img = Image.new("RGB", (W, H))
    for y in range(H):
        for x in range(W):
            img.putpixel((x, y), tuple(max(0, min(255, round(c))) for c in f(x, y)))
    b = io.BytesIO()
    img.save(b, format="PNG")
    return b.getvalue()


def base(x, y):
    return (200, 180, 150) if (x // 8 + y // 8) % 2 == 0 else (40, 60, 110)


def metallic_roughness(x, y):
    return (0, 255 * (0.15 + 0.85 * x / (W - 1)), 255 if y < H // 2 else 0)


def emissive(x, y):
    # glTF images run top-down: rows 12 to 14 lie just above the equator.
    lit = 12 <= y <= 14 and x % 8 < 5
    return (255, 255, 255) if lit else (0, 0, 0)


def normal(x, y):
    # Bumps h = sin(2πx/16)·sin(2πy/8); the normal (−dh/du, −dh/dv, 1), v up the image.
    a, b = 2 * math.pi * x / 16, 2 * math.pi * y / 8
    dx = 0.6 * math.cos(a) * math.sin(b)
    dy = -0.6 * math.sin(a) * math.cos(b)  # rows run down, v up
    n = (-dx, -dy, 1.0)
    l = math.sqrt(sum(c * c for c in n))
    return tuple((c / l * 0.5 + 0.5) * 255 for c in n)


def sphere():
    pos, nor, uv, idx = [], [], [], []
    for j in range(RINGS + 1):
        theta = math.pi * j / RINGS
        for i in range(SEGMENTS + 1):
            phi = 2 * math.pi * i / SEGMENTS
            p = (math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi))
            pos.append(p)
            nor.append(p)
            uv.append((i / SEGMENTS, j / RINGS))
    for j in range(RINGS):
        for i in range(SEGMENTS):
            a = j * (SEGMENTS + 1) + i
            b = a + SEGMENTS + 1
            if j != 0:
                idx += [a, b, a + 1]
            if j != RINGS - 1:
                idx += [a + 1, b, b + 1]
    return pos, nor, uv, idx


def main():
    pos, nor, uv, idx = sphere()
    chunks = [
        b"".join(struct.pack("<3f", *p) for p in pos),
        b"".join(struct.pack("<3f", *n) for n in nor),
        b"".join(struct.pack("<2f", *t) for t in uv),
        b"".join(struct.pack("<I", k) for k in idx),
    ] + [png(f) for f in (base, metallic_roughness, emissive, normal)]
    binary, views = b"", []
    for c in chunks:
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(c)})
        binary += c + b"\0" * (-len(c) % 4)
    n = len(pos)
    doc = {
        "asset": {"version": "2.0", "generator": "lancer scripts/make_panel.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "panel"}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3, "material": 0}]}],
        "materials": [{
            "name": "panel",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0},
                "metallicRoughnessTexture": {"index": 1},
            },
            "emissiveTexture": {"index": 2},
            "emissiveFactor": [1.0, 0.75, 0.375],
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}},
            "normalTexture": {"index": 3, "scale": 1.0},
        }],
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "textures": [{"source": k} for k in range(4)],
        "images": [{"bufferView": 4 + k, "mimeType": "image/png"} for k in range(4)],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": views,
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": [min(p[k] for p in pos) for k in range(3)],
             "max": [max(p[k] for p in pos) for k in range(3)]},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": n, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
        ],
    }
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    glb = struct.pack("<3I", 0x46546C67, 2, 12 + 8 + len(js) + 8 + len(binary))
    glb += struct.pack("<2I", len(js), 0x4E4F534A) + js
    glb += struct.pack("<2I", len(binary), 0x004E4942) + binary
    OUT.write_bytes(glb)
    print(f"wrote {OUT} ({len(glb)} bytes, {len(idx) // 3} triangles)")


if __name__ == "__main__":
    main()
