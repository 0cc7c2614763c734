#!/usr/bin/python3
"""Metrics of bench/direct_light_bench.sh: one frame of every (scene, direct-light mode) against
its converged reference, the render reports' frame and stage times, and the equal-time
efficiency against `power`.

Usage: direct_light_metrics.py OUT_DIR CASES_TSV FRAME
  CASES_TSV: one line per case, tab-separated:
    scene  mode  denoised_dir  raw_dir  reference_dir  denoised_report  raw_report
Writes OUT_DIR/results.csv, OUT_DIR/results.json and OUT_DIR/results.md; prints the Markdown.

Definitions (per eye; linear radiance, RGB):
  relMSE  mean over pixels and channels of (a - r)^2 / (r^2 + 0.01), as `parallax compare`
  PSNR    10 log10(1 / MSE) of both images clamped to [0, 1], as `parallax compare` (peak 1)
  lum     mean Rec. 709 luminance of the image / that of the reference
  ms      median over the frames after the first (which includes kernel compilation) of the
          report's wall_ms (host, first enqueue to last completion)
  eff     1 / (relMSE x seconds per frame), relMSE the mean of the two eyes; eff_raw from the
          --no-denoise run (its relMSE and its frame time), eff_den from the denoised run
  stages  per stage, the median over the frames after the first of the slowest device's
          device_ms (OpenCL profiling), denoised run
Debian's python (python3-numpy, python3-openimageio): run it as /usr/bin/python3.
"""
import csv
import json
import math
import os
import statistics
import sys

import numpy as np
import OpenImageIO as oiio

EYES = ("left", "right")


def read_exr(path):
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise SystemExit(f"direct_light_metrics: cannot read {path}: {buf.geterror()}")
    px = np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float64)
    if px.ndim != 3 or px.shape[2] < 3:
        raise SystemExit(f"direct_light_metrics: {path}: expected an RGB image, got shape {px.shape}")
    return px[:, :, :3]


def luminance(img):
    return 0.2126 * img[:, :, 0] + 0.7152 * img[:, :, 1] + 0.0722 * img[:, :, 2]


def rel_mse(a, r):
    return float(np.mean((a - r) ** 2 / (r * r + 0.01)))


def psnr(a, r):
    mse = float(np.mean((np.clip(a, 0.0, 1.0) - np.clip(r, 0.0, 1.0)) ** 2))
    return math.inf if mse == 0.0 else 10.0 * math.log10(1.0 / mse)


def lum_ratio(a, r):
    ref = float(np.mean(luminance(r)))
    return float(np.mean(luminance(a))) / ref if ref > 0.0 else math.nan


def report_times(path):
    """Median frame wall ms and per-stage medians (slowest device) over frames after the first."""
    with open(path, encoding="utf-8") as f:
        report = json.load(f)
    frames = report.get("frames", [])
    later = frames[1:] if len(frames) > 1 else frames
    if not later:
        raise SystemExit(f"direct_light_metrics: {path} has no frames")
    ms = statistics.median(f["wall_ms"] for f in later)
    stages = {}  # name -> per-frame slowest device
    order = []
    for f in later:
        slowest = {}
        for s in f.get("stages", []):
            key = s["name"]
            if key not in order:
                order.append(key)
            slowest[key] = max(slowest.get(key, 0.0), float(s["device_ms"]))
        for key, v in slowest.items():
            stages.setdefault(key, []).append(v)
    return ms, {k: statistics.median(stages[k]) for k in order}


def fmt(v, digits=3):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "n/a"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    return f"{v:.{digits}g}"


def main():
    if len(sys.argv) != 4:
        raise SystemExit(__doc__)
    out, cases_tsv, frame = sys.argv[1], sys.argv[2], int(sys.argv[3])
    tag = f"frame_{frame:04d}"
    rows = []
    with open(cases_tsv, encoding="utf-8") as f:
        for line in f:
            if not line.strip():
                continue
            scene, mode, den_dir, raw_dir, ref_dir, den_report, raw_report = line.rstrip("\n").split("\t")
            row = {"scene": scene, "mode": mode}
            for eye in EYES:
                ref = read_exr(os.path.join(ref_dir, f"reference_{eye}.exr"))
                den = read_exr(os.path.join(den_dir, f"{tag}_{eye}.exr"))
                raw = read_exr(os.path.join(raw_dir, f"{tag}_{eye}.exr"))
                if den.shape != ref.shape or raw.shape != ref.shape:
                    raise SystemExit(f"direct_light_metrics: {scene}/{mode} {eye}: size differs from the reference")
                row[f"relmse_raw_{eye}"] = rel_mse(raw, ref)
                row[f"relmse_den_{eye}"] = rel_mse(den, ref)
                row[f"psnr_raw_{eye}"] = psnr(raw, ref)
                row[f"psnr_den_{eye}"] = psnr(den, ref)
                row[f"lum_den_{eye}"] = lum_ratio(den, ref)
            row["ms_den"], row["stages"] = report_times(den_report)
            row["ms_raw"], _ = report_times(raw_report)
            for kind in ("raw", "den"):
                err = 0.5 * (row[f"relmse_{kind}_left"] + row[f"relmse_{kind}_right"])
                row[f"eff_{kind}"] = 1.0 / (err * row[f"ms_{kind}"] / 1000.0) if err > 0.0 else math.inf
            rows.append(row)

    power = {r["scene"]: r for r in rows if r["mode"] == "power"}
    for r in rows:
        p = power.get(r["scene"])
        for kind in ("raw", "den"):
            r[f"eff_{kind}_vs_power"] = r[f"eff_{kind}"] / p[f"eff_{kind}"] if p else math.nan

    stage_names = []
    for r in rows:
        stage_names += [s for s in r["stages"] if s not in stage_names]

    columns = ["scene", "mode"]
    for m in ("relmse_raw", "relmse_den", "psnr_raw", "psnr_den", "lum_den"):
        columns += [f"{m}_{eye}" for eye in EYES]
    columns += ["ms_raw", "ms_den", "eff_raw", "eff_den", "eff_raw_vs_power", "eff_den_vs_power"]
    with open(os.path.join(out, "results.csv"), "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(columns + [f"stage_ms:{s}" for s in stage_names])
        for r in rows:
            w.writerow([r[c] for c in columns] + [r["stages"].get(s, "") for s in stage_names])
    with open(os.path.join(out, "results.json"), "w", encoding="utf-8") as f:
        json.dump({"frame": frame, "rows": rows}, f, indent=1, default=lambda v: None)

    md = []
    md.append("| scene | mode | relMSE raw L / R | relMSE den L / R | PSNR den L / R dB | lum den L / R"
              " | ms raw / den | eff raw / den | eff vs power raw / den |")
    md.append("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        md.append(
            f"| {r['scene']} | {r['mode']}"
            f" | {fmt(r['relmse_raw_left'])} / {fmt(r['relmse_raw_right'])}"
            f" | {fmt(r['relmse_den_left'])} / {fmt(r['relmse_den_right'])}"
            f" | {r['psnr_den_left']:.1f} / {r['psnr_den_right']:.1f}"
            f" | {r['lum_den_left']:.3f} / {r['lum_den_right']:.3f}"
            f" | {r['ms_raw']:.0f} / {r['ms_den']:.0f}"
            f" | {fmt(r['eff_raw'])} / {fmt(r['eff_den'])}"
            f" | {fmt(r['eff_raw_vs_power'], 3)} / {fmt(r['eff_den_vs_power'], 3)} |")
    md.append("")
    md.append("Stage times, denoised run (ms; per frame after the first, slowest device, median):")
    md.append("")
    md.append("| scene | mode | " + " | ".join(stage_names) + " |")
    md.append("|---|---|" + "---|" * len(stage_names))
    for r in rows:
        md.append(f"| {r['scene']} | {r['mode']} | " +
                  " | ".join(f"{r['stages'][s]:.1f}" if s in r["stages"] else "" for s in stage_names) + " |")
    text = "\n".join(md) + "\n"
    with open(os.path.join(out, "results.md"), "w", encoding="utf-8") as f:
        f.write(text)
    sys.stdout.write(text)


if __name__ == "__main__":
    main()
