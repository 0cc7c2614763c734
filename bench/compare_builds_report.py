#!/usr/bin/python3
"""The table of bench/compare_builds.sh: reads the bench_trace CSVs and render reports the script
left in TMP (trace_{a,b}_{run}.csv, render_{scene}_{a,b}_{run}.json) and prints, per build, medians
with their [min-max] over the alternated runs and the ratio b / a.

Usage: compare_builds_report.py TMP RUNS A B SCENE...   (SCENE '' = the scene given by flags)
"""
import csv
import json
import os
import statistics
import sys

# Pixels a stage works on, per frame: the left eye's path tracing, the right eye's G-buffer and
# reprojection see one eye; hole filling sees the holes; every other stage both eyes.
ONE_EYE_STAGES = {2, 3, 4}
HOLE_STAGE = 5


def spread(values):
    if not values:
        return "n/a"
    med = statistics.median(values)
    return f"{med:.3g} [{min(values):.3g}-{max(values):.3g}]"


def ratio(a, b):
    return f"{statistics.median(b) / statistics.median(a):.3f}" if a and b and statistics.median(a) > 0 else "n/a"


def trace_table(tmp, runs):
    rows = {}  # (scene, rays, layout) -> side -> {"kernel": [...], "ke": [...]}
    for side in "ab":
        for r in range(1, runs + 1):
            path = os.path.join(tmp, f"trace_{side}_{r}.csv")
            if not os.path.isfile(path):
                return
            with open(path) as f:
                for row in csv.DictReader(f):
                    key = (row["scene"], row["rays"], row["layout"])
                    cell = rows.setdefault(key, {}).setdefault(side, {"kernel": [], "ke": []})
                    cell["kernel"].append(float(row["kernel_mrays"]))
                    cell["ke"].append(float(row["ratio"]))
    print("\n## Trace: bench_trace, kernel Mrays/s and kernel / Embree (Embree from the same run)\n")
    print("| scene | rays | layout | kernel a | kernel b | b/a | k/e a | k/e b |")
    print("|---|---|---|---|---|---|---|---|")
    for (scene, rays, layout), sides in rows.items():
        a, b = sides.get("a"), sides.get("b")
        if not a or not b:
            continue
        print(f"| {scene} | {rays} | {layout} | {spread(a['kernel'])} | {spread(b['kernel'])} | "
              f"{ratio(a['kernel'], b['kernel'])} | {spread(a['ke'])} | {spread(b['ke'])} |")


def render_figures(report):
    """Per frame after the first (which compiles the kernels): ns per pixel of each stage (device
    time summed over devices), hole / left per pixel, and the wall time."""
    w, h = report["width"], report["height"]
    per_stage, hole_ratio, wall = {}, [], []
    for fr in report.get("frames", [])[1:]:
        times = {}
        for s in fr["stages"]:
            times.setdefault((s["stage"], s["name"]), 0.0)
            times[(s["stage"], s["name"])] += s["device_ms"]
        holes = max(0, fr.get("right_pixels", w * h) - fr.get("reprojected", 0))
        per_px = {}
        for (stage, name), ms in times.items():
            pixels = holes if stage == HOLE_STAGE else (w * h if stage in ONE_EYE_STAGES else 2 * w * h)
            if pixels > 0:
                per_px[(stage, name)] = ms * 1e6 / pixels
        for key, v in per_px.items():
            per_stage.setdefault(key, []).append(v)
        left = [v for (stage, _), v in per_px.items() if stage == 2]
        hole = [v for (stage, _), v in per_px.items() if stage == HOLE_STAGE]
        if left and hole and left[0] > 0:
            hole_ratio.append(hole[0] / left[0])
        wall.append(fr["wall_ms"])
    return per_stage, hole_ratio, wall, report.get("makespan_ms")


def render_table(tmp, runs, scene):
    figures = {}
    for side in "ab":
        stages, holes, wall, makespans = {}, [], [], []
        for r in range(1, runs + 1):
            path = os.path.join(tmp, f"render_{scene or 'scene'}_{side}_{r}.json")
            if not os.path.isfile(path):
                return
            with open(path) as f:
                per_stage, hole_ratio, w, makespan = render_figures(json.load(f))
            for k, v in per_stage.items():
                stages.setdefault(k, []).extend(v)
            holes += hole_ratio
            wall += w
            if makespan is not None:
                makespans.append(makespan)
        figures[side] = (stages, holes, wall, makespans)
    a, b = figures["a"], figures["b"]
    print(f"\n## Render: {scene or '(scene given by flags)'}, per frame after the first\n")
    print("| stage | ns/pixel a | ns/pixel b | b/a |")
    print("|---|---|---|---|")
    for key in sorted(set(a[0]) | set(b[0])):
        va, vb = a[0].get(key, []), b[0].get(key, [])
        print(f"| {key[0]} {key[1]} | {spread(va)} | {spread(vb)} | {ratio(va, vb)} |")
    print(f"| hole filling per hole / left per pixel | {spread(a[1])} | {spread(b[1])} | {ratio(a[1], b[1])} |")
    print(f"| frame wall ms | {spread(a[2])} | {spread(b[2])} | {ratio(a[2], b[2])} |")
    print(f"| makespan ms (whole run, first frame included) | {spread(a[3])} | {spread(b[3])} | {ratio(a[3], b[3])} |")


def main():
    tmp, runs, a, b, scenes = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5:]
    print(f"a = {a}\nb = {b}\n(medians [min-max] over {runs} alternated run(s) per build)")
    trace_table(tmp, runs)
    for scene in scenes:
        render_table(tmp, runs, scene)


if __name__ == "__main__":
    main()
