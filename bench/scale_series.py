#!/usr/bin/python3
"""Paper-scale starts: time, peak memory and bytes per triangle of `parallax render --frames 1`
on generated heightfields of 0.25M to 10M triangles, cold (no BVH cache) and warm (cache
filled by the cold run), beside Mitsuba 3 (scalar_rgb: load + build + 1 spp) on the same mesh.

Each size is a square grid of quads over a smooth relief, two triangles a quad, written once
under --work as binary glTF (parallax, with a sun and a sky in a scene JSON beside it) and binary
PLY (Mitsuba); both hold the same indexed vertices and triangles. Every run goes through
`/usr/bin/time -v` (wall time, maximum resident set size). Mitsuba 3 comes from PyPI into a
virtual environment under the build folder (made from /usr/bin/python3 with
--system-site-packages); without network its columns read n/a.

PoCL's kernel cache is primed first with a small mesh (the kernels are the same at every size),
so that no cold run pays for compiling them. --first-run adds a run beside each cold one with an
empty PoCL cache as well, which compiles the kernels for the scene's features as a user's very
first run does, and a table of those runs. Every run is one raw frame, which `--kernel-build auto`
builds quickly (the optimiser off: the same images, slower kernels; docs/measurements.md, "Quick
kernel builds for short runs"), as it does for a user.

Usage: bench/scale_series.py [--sizes 0.25,1,4,10] [--build build] [--work build/scale-series]
                             [--width 320] [--height 180] [--devices 2] [--repeat 3] [--offline]
                             [--smooth] [--first-run]
--smooth writes per-vertex normals and texture coordinates as well (as scanned and modelled
meshes come), which parallax keeps in indexed shading records (16 bytes a triangle beside each
vertex's normal and uv once) instead of flat ones' 16 bytes.
Sizes are in millions of triangles. Each start runs --repeat times (cold parallax and Mitsuba
alternating); the table gives the median time, its range and the highest peak. Writes
<work>/results.csv and prints a Markdown table.
"""
import argparse
import csv
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import time

import numpy as np


def die(msg):
    print(f"scale_series: error: {msg}", file=sys.stderr)
    sys.exit(2)


def grid_for(triangles):
    """Quads per side whose 2 n^2 triangles come closest to `triangles`."""
    return max(1, int(round(math.sqrt(triangles / 2.0))))


def heightfield_normals_uvs(n):
    """Per-vertex unit normals (the relief's analytic gradient) and texture coordinates (x, z
    mapped to [0, 1]) of heightfield(n)'s vertices, float32 [V,3] and [V,2]."""
    s = np.linspace(-1.0, 1.0, n + 1, dtype=np.float64)
    x, z = np.meshgrid(s, s)
    dx = 0.08 * 9.0 * np.cos(9.0 * x) * np.cos(7.0 * z) + 0.05 * 23.0 * np.cos(23.0 * x + 11.0 * z)
    dz = -0.08 * 7.0 * np.sin(9.0 * x) * np.sin(7.0 * z) + 0.05 * 11.0 * np.cos(23.0 * x + 11.0 * z)
    nrm = np.stack([-dx, np.ones_like(dx), -dz], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    uv = np.stack([0.5 * (x + 1.0), 0.5 * (z + 1.0)], axis=-1)
    return nrm.reshape(-1, 3).astype(np.float32), uv.reshape(-1, 2).astype(np.float32)


def heightfield(n):
    """(positions float32 [V,3], indices uint32 [T,3]) of an n x n quad grid over [-1, 1]^2."""
    s = np.linspace(-1.0, 1.0, n + 1, dtype=np.float64)
    x, z = np.meshgrid(s, s)
    y = 0.08 * np.sin(9.0 * x) * np.cos(7.0 * z) + 0.05 * np.sin(23.0 * x + 11.0 * z)
    pos = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    i = np.arange(n, dtype=np.uint32)
    a = (i[None, :] + (n + 1) * i[:, None]).reshape(-1)  # each quad's corner (row, col)
    b, c, d = a + 1, a + (n + 1), a + (n + 2)
    # Counter-clockwise seen from above (+y): normals point up.
    idx = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)]).astype(np.uint32)
    return pos, idx


def write_glb(path, pos, idx, nrm=None, uv=None):
    bin_blob = idx.tobytes() + pos.tobytes()
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": idx.nbytes, "target": 34963},
             {"buffer": 0, "byteOffset": idx.nbytes, "byteLength": pos.nbytes, "target": 34962}]
    accessors = [{"bufferView": 0, "componentType": 5125, "count": int(idx.size), "type": "SCALAR"},
                 {"bufferView": 1, "componentType": 5126, "count": int(pos.shape[0]), "type": "VEC3",
                  "min": pos.min(axis=0).tolist(), "max": pos.max(axis=0).tolist()}]
    attributes = {"POSITION": 1}
    for name, data, kind in (("NORMAL", nrm, "VEC3"), ("TEXCOORD_0", uv, "VEC2")):
        if data is None:
            continue
        views.append({"buffer": 0, "byteOffset": len(bin_blob), "byteLength": data.nbytes, "target": 34962})
        accessors.append({"bufferView": len(views) - 1, "componentType": 5126, "count": int(data.shape[0]),
                          "type": kind})
        attributes[name] = len(accessors) - 1
        bin_blob += data.tobytes()
    pad = (-len(bin_blob)) % 4
    bin_blob += b"\0" * pad
    gltf = {
        "asset": {"version": "2.0", "generator": "parallax bench/scale_series.py"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": 0, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.55, 0.5, 1.0], "metallicFactor": 0.0,
                                                 "roughnessFactor": 1.0}}],
        "buffers": [{"byteLength": len(bin_blob)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    js = json.dumps(gltf).encode()
    js += b" " * ((-len(js)) % 4)
    total = 12 + 8 + len(js) + 8 + len(bin_blob)
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, total))
        f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
        f.write(struct.pack("<II", len(bin_blob), 0x004E4942) + bin_blob)
    os.replace(tmp, path)


def write_ply(path, pos, idx, nrm=None, uv=None):
    tmp = path + ".tmp"
    props = "property float x\nproperty float y\nproperty float z\n"
    columns = [pos]
    if nrm is not None:
        props += "property float nx\nproperty float ny\nproperty float nz\n"
        columns.append(nrm)
    if uv is not None:
        props += "property float u\nproperty float v\n"
        columns.append(uv)
    with open(tmp, "wb") as f:
        f.write(("ply\nformat binary_little_endian 1.0\n"
                 f"element vertex {pos.shape[0]}\n{props}"
                 f"element face {idx.shape[0]}\nproperty list uchar uint vertex_indices\nend_header\n").encode())
        f.write(np.concatenate(columns, axis=1).astype("<f4").tobytes())
        faces = np.empty(idx.shape[0], dtype=[("n", "u1"), ("v", "<u4", 3)])
        faces["n"] = 3
        faces["v"] = idx
        f.write(faces.tobytes())
    os.replace(tmp, path)


SUN_DIR = [0.4, 0.8, 0.45]


def write_scene_json(path, glb_name):
    scene = {
        "mesh": glb_name,
        "meters_per_unit": 1,
        "sun": {"direction": SUN_DIR, "radiance": [110000, 105000, 95000], "angular_radius_deg": 0.27},
        "sky": {"zenith": [0.3, 0.5, 1.0], "horizon": [0.8, 0.85, 0.9], "ground": [0.2, 0.2, 0.2]},
    }
    with open(path, "w") as f:
        json.dump(scene, f, indent=1)


def timed(cmd, env=None, log=None):
    """Runs cmd under /usr/bin/time -v: (exit code, wall s, peak RSS MiB)."""
    t0 = time.monotonic()
    p = subprocess.run(["/usr/bin/time", "-v"] + cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True)
    wall = time.monotonic() - t0
    if log:
        with open(log, "w") as f:
            f.write(" ".join(cmd) + "\n" + p.stdout)
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stdout)
    rss = int(m.group(1)) / 1024.0 if m else float("nan")
    return p.returncode, wall, rss


MITSUBA_SCRIPT = r"""
import sys, mitsuba as mi
mi.set_variant("scalar_rgb")
ply, w, h = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
T = mi.ScalarTransform4f
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "path", "max_depth": 7},
    "sensor": {"type": "perspective", "fov": 50,
               "to_world": T().look_at(origin=[0, 1.6, 2.4], target=[0, 0, 0], up=[0, 1, 0]),
               "film": {"type": "hdrfilm", "width": w, "height": h},
               "sampler": {"type": "independent", "sample_count": 1}},
    "mesh": {"type": "ply", "filename": ply, "bsdf": {"type": "diffuse"}},
    "sun": {"type": "directional", "direction": [-0.4, -0.8, -0.45], "irradiance": 7.0},
    "sky": {"type": "constant", "radiance": 0.6},
})
img = mi.render(scene, spp=1)
print("mitsuba rendered", img.shape)
"""


def mitsuba_python(build, offline):
    venv = os.path.join(build, "scale-venv")
    py = os.path.join(venv, "bin", "python")
    probe = lambda: os.path.exists(py) and subprocess.run([py, "-c", "import mitsuba"],
                                                          capture_output=True).returncode == 0
    if probe():
        return py
    if offline:
        return None
    print("[scale_series] installing Mitsuba 3 from PyPI into", venv, file=sys.stderr)
    if subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv]).returncode != 0:
        print("[scale_series] could not make the virtual environment (python3-venv?): Mitsuba columns n/a",
              file=sys.stderr)
        return None
    if subprocess.run([py, "-m", "pip", "install", "--quiet", "mitsuba"]).returncode != 0 or not probe():
        print("[scale_series] could not install mitsuba (no network?): Mitsuba columns n/a", file=sys.stderr)
        return None
    return py


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="0.25,1,4,10", help="millions of triangles, comma-separated")
    ap.add_argument("--build", default=os.environ.get("PARALLAX_BUILD_DIR", "build"))
    ap.add_argument("--work", default=None, help="meshes, logs and results (default: BUILD/scale-series)")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=180)
    ap.add_argument("--devices", type=int, default=2)
    ap.add_argument("--offline", action="store_true", help="never ask PyPI (Mitsuba columns n/a unless installed)")
    ap.add_argument("--smooth", action="store_true",
                    help="meshes with per-vertex NORMAL and TEXCOORD_0 (PLY: nx ny nz u v), as scanned and modelled "
                         "meshes come; without it the heightfields have positions only (flat triangles)")
    ap.add_argument("--first-run", action="store_true",
                    help="also time first runs: no BVH cache and an empty PoCL kernel cache (each one compiles "
                         "the kernels for the scene's features, as a user's very first run does)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs of each start (cold parallax and Mitsuba alternate); the table gives medians")
    a = ap.parse_args()
    try:
        sizes = [float(s) for s in a.sizes.split(",") if s]
    except ValueError:
        die(f"--sizes needs numbers, got '{a.sizes}'")
    if not sizes or any(s <= 0 or s > 200 for s in sizes):
        die("--sizes: each size must be in (0, 200] million triangles")
    if a.width < 1 or a.height < 1 or a.devices < 1 or a.repeat < 1:
        die("--width, --height, --devices and --repeat must be positive")
    parallax = os.path.join(a.build, "parallax")
    if not os.access(parallax, os.X_OK):
        die(f"{parallax} not found: build first (scripts/build), or pass --build DIR")
    work = a.work or os.path.join(a.build, "scale-series")
    os.makedirs(os.path.join(work, "logs"), exist_ok=True)
    mpy = mitsuba_python(a.build, a.offline)
    # PoCL compiles the kernels on a first run and caches them; that cost does not depend on the
    # scene's size (every heightfield has the same kernel features), so a small mesh primes the
    # cache before anything is timed. It has the series' vertex attributes: with --smooth the
    # kernels read indexed shading records, which a flat mesh's build of them does not (a prime
    # without normals and uvs left the first timed run compiling its kernels).
    prime_pos, prime_idx = heightfield(8)
    prime_nrm, prime_uv = heightfield_normals_uvs(8) if a.smooth else (None, None)
    prime = os.path.join(work, "prime-smooth" if a.smooth else "prime")
    write_glb(prime + ".glb", prime_pos, prime_idx, prime_nrm, prime_uv)
    write_scene_json(prime + ".json", os.path.basename(prime) + ".glb")
    print("[scale_series] priming the kernel cache", file=sys.stderr)
    timed([parallax, "render", "--scene", prime + ".json", "--frames", "1", "--devices", str(a.devices), "--width",
           str(a.width), "--height", str(a.height), "--no-denoise", "--overwrite", "--out",
           os.path.join(work, "out")])
    rows = []
    for s in sizes:
        n = grid_for(s * 1e6)
        tris = 2 * n * n
        tag = f"smooth-{tris}" if a.smooth else f"{tris}"
        glb, ply, js = (os.path.join(work, f"heightfield-{tag}.{ext}") for ext in ("glb", "ply", "json"))
        if not (os.path.exists(glb) and os.path.exists(ply) and os.path.exists(js)):
            print(f"[scale_series] generating {tris} triangles", file=sys.stderr)
            pos, idx = heightfield(n)
            nrm, uv = heightfield_normals_uvs(n) if a.smooth else (None, None)
            write_glb(glb, pos, idx, nrm, uv)
            write_ply(ply, pos, idx, nrm, uv)
            write_scene_json(js, os.path.basename(glb))
            del pos, idx, nrm, uv
        row = {"triangles": tris, "glb_mib": os.path.getsize(glb) / 2**20}
        common = ["render", "--scene", js, "--frames", "1", "--spp", "1", "--devices", str(a.devices), "--width",
                  str(a.width), "--height", str(a.height), "--no-denoise", "--overwrite"]
        cache = os.path.join(work, "bvh-cache")
        env = dict(os.environ, PARALLAX_CACHE_DIR=cache)
        out = ["--out", os.path.join(work, "out")]
        script = os.path.join(work, "mitsuba_render.py")
        if mpy:
            with open(script, "w") as f:
                f.write(MITSUBA_SCRIPT)
        # Cold (no BVH cache at all) and Mitsuba alternate, run after run: on a virtual machine the
        # time to touch fresh memory varies from run to run (a 10M cold start: 8.6 to 16 s, with
        # 1.5 to 9 s of system time), and both then meet the machine in the same states.
        runs = {"cold": [], "warm": [], "mitsuba": [], "first": []}
        for r in range(a.repeat):
            print(f"[scale_series] {tris} triangles: parallax cold ({r + 1}/{a.repeat})", file=sys.stderr)
            rc, wall, rss = timed([parallax] + common + out, dict(env, PARALLAX_BVH_CACHE="off"),
                                  os.path.join(work, "logs", f"parallax-cold-{tag}-{r + 1}.txt"))
            if rc != 0:
                die(f"parallax failed on {tris} triangles (cold): see {work}/logs/parallax-cold-{tag}-{r + 1}.txt")
            runs["cold"].append((wall, rss))
            if a.first_run:
                print(f"[scale_series] {tris} triangles: parallax first run ({r + 1}/{a.repeat})", file=sys.stderr)
                kernels = os.path.join(work, "pocl-first-run")
                shutil.rmtree(kernels, ignore_errors=True)
                rc, wall, rss = timed([parallax] + common + out,
                                      dict(env, PARALLAX_BVH_CACHE="off", POCL_CACHE_DIR=kernels),
                                      os.path.join(work, "logs", f"parallax-first-{tag}-{r + 1}.txt"))
                shutil.rmtree(kernels, ignore_errors=True)
                if rc != 0:
                    die(f"parallax failed on {tris} triangles (first run): see {work}/logs/"
                        f"parallax-first-{tag}-{r + 1}.txt")
                runs["first"].append((wall, rss))
            if mpy:
                print(f"[scale_series] {tris} triangles: Mitsuba 3 ({r + 1}/{a.repeat})", file=sys.stderr)
                rc, wall, rss = timed([mpy, script, ply, str(a.width), str(a.height)], None,
                                      os.path.join(work, "logs", f"mitsuba-{tag}-{r + 1}.txt"))
                if rc == 0:
                    runs["mitsuba"].append((wall, rss))
        # Warm: a cache the first run fills, then the timed runs.
        timed([parallax] + common + out, env)
        for r in range(a.repeat):
            print(f"[scale_series] {tris} triangles: parallax warm ({r + 1}/{a.repeat})", file=sys.stderr)
            rc, wall, rss = timed([parallax] + common + out, env,
                                  os.path.join(work, "logs", f"parallax-warm-{tag}-{r + 1}.txt"))
            if rc != 0:
                die(f"parallax failed on {tris} triangles (warm): see {work}/logs/parallax-warm-{tag}-{r + 1}.txt")
            runs["warm"].append((wall, rss))
        for key in ("cold", "warm", "mitsuba", "first"):
            if runs[key]:
                walls = sorted(w for w, _ in runs[key])
                row[f"{key}_s"] = float(np.median(walls))
                row[f"{key}_s_min"], row[f"{key}_s_max"] = walls[0], walls[-1]
                row[f"{key}_mib"] = max(m for _, m in runs[key])  # the highest peak of the runs
        rows.append(row)
    fields = ["triangles", "glb_mib", "runs", "cold_s", "cold_s_min", "cold_s_max", "cold_mib", "warm_s", "warm_s_min",
              "warm_s_max", "warm_mib", "mitsuba_s", "mitsuba_s_min", "mitsuba_s_max", "mitsuba_mib", "first_s",
              "first_s_min", "first_s_max", "first_mib"]
    with open(os.path.join(work, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: (a.repeat if k == "runs" else r.get(k)) for k in fields})
    fmt = lambda v, d=1: "n/a" if v is None else f"{v:.{d}f}"
    bpt = lambda mib, t: "n/a" if mib is None else f"{mib * 2**20 / t:.0f}"
    span = lambda r, k: "" if a.repeat == 1 or r.get(k + "_s") is None else f" ({r[k + '_s_min']:.1f}-{r[k + '_s_max']:.1f})"
    ratio = lambda r: "n/a" if not r.get("mitsuba_s") else f"{r['cold_s'] / r['mitsuba_s']:.2f}"
    print(f"Median of {a.repeat} run(s) (range); peak: the highest of the runs.")
    print("| triangles | parallax cold s | peak MiB | B/triangle | warm s | peak MiB | B/triangle | Mitsuba 3 s | peak MiB "
          "| B/triangle | cold / Mitsuba |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        t = r["triangles"]
        print(f"| {t / 1e6:.2f}M | {fmt(r['cold_s'])}{span(r, 'cold')} | {fmt(r['cold_mib'], 0)} | "
              f"{bpt(r['cold_mib'], t)} | {fmt(r['warm_s'])}{span(r, 'warm')} | {fmt(r['warm_mib'], 0)} | "
              f"{bpt(r['warm_mib'], t)} | {fmt(r.get('mitsuba_s'))}{span(r, 'mitsuba')} | "
              f"{fmt(r.get('mitsuba_mib'), 0)} | {bpt(r.get('mitsuba_mib'), t)} | {ratio(r)} |")
    if a.first_run:
        print()
        print("First runs (no BVH cache, an empty PoCL kernel cache):")
        print("| triangles | parallax first run s | peak MiB | B/triangle | first run / Mitsuba |")
        print("|---|---|---|---|---|")
        for r in rows:
            t = r["triangles"]
            first = "n/a" if not (r.get("mitsuba_s") and r.get("first_s")) else f"{r['first_s'] / r['mitsuba_s']:.2f}"
            print(f"| {t / 1e6:.2f}M | {fmt(r.get('first_s'))}{span(r, 'first')} | {fmt(r.get('first_mib'), 0)} | "
                  f"{bpt(r.get('first_mib'), t)} | {first} |")
    print(f"(results: {work}/results.csv; logs: {work}/logs)", file=sys.stderr)


if __name__ == "__main__":
    main()
