#!/usr/bin/env python3
"""Writes a small animated glTF for the script tests (standard library only): a grey floor and
a red unit cube that slides from x = -1.5 to 1.5 and turns 90 degrees about y over one second
(clip "slide", LINEAR), seen by the file's own camera.

Usage: write_animated_gltf.py OUT.gltf [--still] [--copies N]
  --still     no animation: a static file
  --copies N  N more nodes draw the cube's mesh, standing still in a ring on the floor (in a
              static file the loader stores the mesh once and draws it as instances)
"""
import base64
import json
import math
import struct
import sys

args = sys.argv[1:]
if not args or args[0].startswith("-"):
    sys.exit(__doc__)
out_path, still, copies = args[0], "--still" in args, 0
if "--copies" in args:
    copies = int(args[args.index("--copies") + 1])

buf = bytearray()
views, accessors = [], []


def accessor(values, fmt, component, count, kind):
    offset = len(buf)
    buf.extend(struct.pack("<%d%s" % (len(values), fmt), *values))
    while len(buf) % 4:
        buf.append(0)
    views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(buf) - offset})
    accessors.append({"bufferView": len(views) - 1, "componentType": component, "count": count, "type": kind})
    return len(accessors) - 1


# The cube: four corners and a normal per face.
faces = [((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, 1, 0), (0, 0, -1)), ((0, 1, 0), (0, 0, 1), (1, 0, 0)),
         ((0, -1, 0), (0, 0, -1), (1, 0, 0)), ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]
pos, nor, idx = [], [], []
for n, u, v in faces:
    base = len(pos) // 3
    for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        pos += [0.5 * (n[k] + su * u[k] + sv * v[k]) for k in range(3)]
        nor += list(n)
    idx += [base, base + 1, base + 2, base, base + 2, base + 3]
cube = {"attributes": {"POSITION": accessor(pos, "f", 5126, 24, "VEC3"), "NORMAL": accessor(nor, "f", 5126, 24, "VEC3")},
        "indices": accessor(idx, "H", 5123, 36, "SCALAR"), "material": 0}
floor = {"attributes": {"POSITION": accessor([-4, 0, -4, 4, 0, -4, 4, 0, 4, -4, 0, 4], "f", 5126, 4, "VEC3"),
                        "NORMAL": accessor([0, 1, 0] * 4, "f", 5126, 4, "VEC3")},
         "indices": accessor([0, 2, 1, 0, 3, 2], "H", 5123, 6, "SCALAR"), "material": 1}
times = accessor([0.0, 0.5, 1.0], "f", 5126, 3, "SCALAR")
moves = accessor([-1.5, 0.5, 0, 0, 0.5, 0, 1.5, 0.5, 0], "f", 5126, 3, "VEC3")
turns = []
for t in (0.0, 0.5, 1.0):
    a = t * math.pi / 2
    turns += [0, math.sin(a / 2), 0, math.cos(a / 2)]
turns = accessor(turns, "f", 5126, 3, "VEC4")
doc = {
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
    "nodes": [{"mesh": 0, "translation": [-1.5, 0.5, 0], "name": "cube"}, {"mesh": 1, "name": "floor"},
              {"camera": 0, "translation": [0, 2.5, 6], "rotation": [-0.199, 0, 0, 0.98]}],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
    "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.1, 1], "metallicFactor": 0}},
                  {"pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1], "metallicFactor": 0}}],
    "meshes": [{"primitives": [cube]}, {"primitives": [floor]}],
    "animations": [{"name": "slide",
                    "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                                 {"sampler": 1, "target": {"node": 0, "path": "rotation"}}],
                    "samplers": [{"input": times, "output": moves}, {"input": times, "output": turns}]}],
    "accessors": accessors, "bufferViews": views,
    "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(buf)).decode()}],
}
# The ring of still copies: turned, scaled and lifted so that no two are alike.
for i in range(copies):
    a = 2 * math.pi * i / max(1, copies)
    s = 0.35 + 0.25 * ((i * 7) % 5) / 4
    doc["nodes"].append({"mesh": 0, "translation": [2.6 * math.cos(a), s / 2, -1.0 + 1.6 * math.sin(a)],
                         "rotation": [0, math.sin(a / 2), 0, math.cos(a / 2)], "scale": [s, s, s]})
    doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
if still:
    del doc["animations"]
with open(out_path, "w") as f:
    json.dump(doc, f)
