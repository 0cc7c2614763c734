#!/usr/bin/python3
"""Metrics of scripts/evaluate_denoiser: the denoised 1-spp frame against converged references.

Usage: PYTHON scripts/evaluate_denoiser.py OUT CASES_TSV FRAME

PYTHON is Debian's /usr/bin/python3 (numpy, OpenImageIO: python3-numpy, python3-openimageio) or
the evaluation's virtual environment made from it with --system-site-packages, which adds NVIDIA's
FLIP (PyPI flip-evaluator) and Intel Open Image Denoise (PyPI pyoidn). Without either package its
columns read "n/a".

CASES_TSV (written by scripts/evaluate_denoiser), one case per line, tab-separated:
  case  scene  camera  fps  denoised_dir  raw_dir  reference_dir  previous_reference_dir  report_json
previous_reference_dir is "-" where there is none (moving camera). Writes OUT/results.csv and
OUT/summary.md, and OUT/cases/CASE/oidn_{color,aux}_{left,right}.exr.

Definitions (one each, used for every column):
  luminance   Y = 0.2126 R + 0.7152 G + 0.0722 B of the linear radiance (Rec. 709).
  bias        mean Y of the image / mean Y of the reference - 1, in %.
  PSNR        on linear radiance: both images clamped to [0, peak] per channel, MSE over all pixels
              and channels, 10 log10(peak^2 / MSE); peak = the reference's 99.9th percentile of Y.
  FLIP        mean LDR-FLIP (flip-evaluator, default 67 pixels per degree) of the sRGB images:
              linear radiance x exposure 1, clamped to [0, 1], sRGB-encoded (as the PNGs are,
              without the 8-bit rounding).
  flicker     mean LDR-FLIP between frame FRAME-1 (as FLIP's reference) and frame FRAME of the
              same method; for the references, frame FRAME-1's and FRAME's references of the still
              camera: two independent sample streams of one view, i.e. the references' own noise.
  SVGF ms     per frame after the first, the slowest device's device time in stages 6 (SVGF) and
              7 (its history copies), from render --report; the median over those frames.
"""
import csv
import json
import math
import os
import statistics
import sys
import time

import numpy as np

try:
    import OpenImageIO as oiio
except ImportError:
    sys.exit("evaluate_denoiser: error: python3-openimageio is missing for this python (run scripts/install-deps)")

try:
    import flip_evaluator
except Exception:  # not installed, or a broken install: the FLIP columns are n/a
    flip_evaluator = None
try:
    import pyoidn
except Exception:
    pyoidn = None

NA = "n/a"
METHODS = [("svgf", "SVGF"), ("raw", "raw 1 spp"), ("oidn_color", "OIDN colour"), ("oidn_aux", "OIDN +albedo+normal")]
COLUMNS = (["case", "scene", "camera", "fps", "eye", "width", "height", "frame", "psnr_peak"]
           + [f"{m}_{k}" for m, _ in METHODS for k in ("lum_bias_pct", "psnr_db", "flip")]
           + ["flicker_svgf_flip", "flicker_raw_flip", "flicker_oidn_aux_flip", "flicker_reference_flip",
              "svgf_ms", "frame_ms", "oidn_aux_ms"])


class EvalError(Exception):
    pass


def read_exr(path):
    if not os.path.isfile(path):
        raise EvalError(f"missing image {path}")
    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    if buf.has_error or px is None or px.ndim != 3 or px.shape[2] < 3:
        raise EvalError(f"cannot read {path} as an RGB image: {buf.geterror()}")
    px = np.ascontiguousarray(px[:, :, :3], dtype=np.float32)
    if not np.isfinite(px).all():
        raise EvalError(f"{path} has NaN or infinite pixels")
    return px


def write_exr(path, px):
    spec = oiio.ImageSpec(px.shape[1], px.shape[0], 3, oiio.FLOAT)
    out = oiio.ImageOutput.create(path)
    if not out or not out.open(path, spec) or not out.write_image(px) or not out.close():
        raise EvalError(f"cannot write {path}: {oiio.geterror()}")


def luminance(px):
    return 0.2126 * px[:, :, 0] + 0.7152 * px[:, :, 1] + 0.0722 * px[:, :, 2]


def bias_pct(img, ref):
    mean_ref = float(luminance(ref).mean())
    return 100.0 * (float(luminance(img).mean()) / mean_ref - 1.0) if mean_ref > 0 else math.nan


def psnr(img, ref, peak):
    if not peak > 0:
        return math.nan
    a = np.clip(img, 0.0, peak).astype(np.float64)
    r = np.clip(ref, 0.0, peak).astype(np.float64)
    mse = float(np.mean((a - r) ** 2))
    return math.inf if mse == 0 else 10.0 * math.log10(peak * peak / mse)


def srgb(px):
    c = np.clip(px, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055).astype(np.float32)


def flip(test, ref):
    if flip_evaluator is None:
        return None
    _, mean, _ = flip_evaluator.evaluate(srgb(ref), srgb(test), "LDR", inputsRGB=True, applyMagma=False)
    return float(mean)


def oidn(color, albedo=None, normal=None):
    if pyoidn is None:
        return None
    if albedo is None:
        return pyoidn.denoise(color, hdr=True)
    # The auxiliaries come from the pixel's G-buffer ray (one ray, no sampling noise): cleanAux.
    return pyoidn.denoise(color, np.clip(albedo, 0.0, 1.0), np.clip(normal, -1.0, 1.0), hdr=True, clean_aux=True)


def frame_times(report):
    """Per frame after the first (which compiles the kernels) of a `render --report` JSON: the
    slowest device's device time in stages 6 (SVGF) and 7 (its history copies), and the wall time.
    bench/compare_builds.sh reads reports with this too."""
    svgf, wall = [], []
    for fr in report.get("frames", [])[1:]:
        per_device = {}
        for s in fr["stages"]:
            if s["stage"] in (6, 7):
                per_device[s["device"]] = per_device.get(s["device"], 0.0) + s["device_ms"]
        svgf.append(max(per_device.values()) if per_device else 0.0)
        wall.append(fr["wall_ms"])
    return svgf, wall


def svgf_times(report_path, frame):
    if not os.path.isfile(report_path):
        raise EvalError(f"missing render report {report_path}")
    with open(report_path) as f:
        rep = json.load(f)
    frames = rep.get("frames", [])
    if len(frames) < frame + 1:
        raise EvalError(f"{report_path} holds {len(frames)} frame(s), expected {frame + 1}")
    svgf, wall = frame_times(rep)
    if not svgf or max(svgf) <= 0:
        raise EvalError(f"{report_path} has no SVGF stage times (was the render denoised?)")
    return statistics.median(svgf), statistics.median(wall)


def fmt(v, digits=2):
    if v is None:
        return NA
    if isinstance(v, str):
        return v
    if math.isinf(v):
        return "inf"
    if math.isnan(v):
        return NA
    return f"{v:.{digits}f}"


def evaluate_case(out, row, frame, oidn_ms):
    case, scene, camera, fps, den_dir, raw_dir, ref_dir, prev_ref_dir, report = row
    svgf_ms, frame_ms = svgf_times(report, frame)
    case_dir = os.path.join(out, "cases", case)
    os.makedirs(case_dir, exist_ok=True)
    rows = []
    for eye in ("left", "right"):
        ref = read_exr(os.path.join(ref_dir, f"reference_{eye}.exr"))
        ref_prev = read_exr(os.path.join(prev_ref_dir, f"reference_{eye}.exr")) if prev_ref_dir != "-" else None
        name = lambda f, suffix="": f"frame_{f:04d}_{eye}{suffix}.exr"  # noqa: E731
        images = {
            "svgf": read_exr(os.path.join(den_dir, name(frame))),
            "raw": read_exr(os.path.join(raw_dir, name(frame))),
        }
        prev = {
            "svgf": read_exr(os.path.join(den_dir, name(frame - 1))),
            "raw": read_exr(os.path.join(raw_dir, name(frame - 1))),
        }
        albedo = read_exr(os.path.join(raw_dir, name(frame, "_albedo")))
        normal = read_exr(os.path.join(raw_dir, name(frame, "_normal")))
        albedo_prev = read_exr(os.path.join(raw_dir, name(frame - 1, "_albedo")))
        normal_prev = read_exr(os.path.join(raw_dir, name(frame - 1, "_normal")))
        for what, img in list(images.items()) + [("reference", ref)]:
            if img.shape != images["svgf"].shape:
                raise EvalError(f"{case} {eye}: the {what} image is {img.shape[1]}x{img.shape[0]}, the denoised "
                                f"one {images['svgf'].shape[1]}x{images['svgf'].shape[0]}")
        if pyoidn is not None:
            images["oidn_color"] = oidn(images["raw"])
            t0 = time.perf_counter()
            images["oidn_aux"] = oidn(images["raw"], albedo, normal)
            oidn_ms.append(1000.0 * (time.perf_counter() - t0))
            prev["oidn_aux"] = oidn(prev["raw"], albedo_prev, normal_prev)
            for m in ("oidn_color", "oidn_aux"):
                write_exr(os.path.join(case_dir, f"{m}_{eye}.exr"), images[m])
        peak = float(np.percentile(luminance(ref), 99.9))
        r = {"case": case, "scene": scene, "camera": camera, "fps": fps, "eye": eye, "width": ref.shape[1],
             "height": ref.shape[0], "frame": frame, "psnr_peak": f"{peak:.6g}"}
        for m, _ in METHODS:
            img = images.get(m)
            r[f"{m}_lum_bias_pct"] = fmt(bias_pct(img, ref) if img is not None else None, 3)
            r[f"{m}_psnr_db"] = fmt(psnr(img, ref, peak) if img is not None else None, 3)
            r[f"{m}_flip"] = fmt(flip(img, ref) if img is not None else None, 4)
        for m in ("svgf", "raw", "oidn_aux"):
            r[f"flicker_{m}_flip"] = fmt(flip(images[m], prev[m]) if m in prev else None, 4)
        r["flicker_reference_flip"] = fmt(flip(ref, ref_prev) if ref_prev is not None else None, 4)
        r["svgf_ms"] = fmt(svgf_ms, 3)
        r["frame_ms"] = fmt(frame_ms, 3)
        r["oidn_aux_ms"] = NA  # filled in once the warm-up call is known (below)
        rows.append(r)
    return rows


def table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def summary(out, rows, frame, params):
    md = ["# Denoiser evaluation: what a viewer sees at 1 spp", ""]
    md.append(f"Frame {frame} of a {frame + 1}-frame run of `parallax render --pipeline proposed` "
              f"({params.get('width')}x{params.get('height')} per eye, {params.get('spp')} spp, "
              f"{params.get('bounces')} bounces, {params.get('devices')} devices), both eyes, against "
              f"`parallax reference` of the same frame at {params.get('ref_spp')} spp. Still camera: "
              "`--fps 1000000`; moving: `--fps 30`.")
    md.append("")
    if flip_evaluator is None:
        md.append("FLIP: **n/a** (flip-evaluator not available: no network, or `--offline` without a virtual "
                  "environment that has it).")
    if pyoidn is None:
        md.append("OIDN: **n/a** (pyoidn not available: no network, or `--offline` without a virtual "
                  "environment that has it).")
    md.append("")
    md.append("## Against the reference")
    md.append("")
    md.append(table(
        ["case", "eye", "SVGF bias %", "SVGF PSNR dB", "raw PSNR dB", "SVGF FLIP", "OIDN colour bias %",
         "OIDN colour PSNR dB", "OIDN colour FLIP", "OIDN aux bias %", "OIDN aux PSNR dB", "OIDN aux FLIP"],
        [[r["case"], r["eye"], r["svgf_lum_bias_pct"], r["svgf_psnr_db"], r["raw_psnr_db"], r["svgf_flip"],
          r["oidn_color_lum_bias_pct"], r["oidn_color_psnr_db"], r["oidn_color_flip"], r["oidn_aux_lum_bias_pct"],
          r["oidn_aux_psnr_db"], r["oidn_aux_flip"]] for r in rows]))
    md.append("")
    md.append("## Flicker and time")
    md.append("")
    md.append(table(
        ["case", "eye", f"SVGF FLIP {frame - 1}→{frame}", f"raw FLIP {frame - 1}→{frame}",
         f"OIDN aux FLIP {frame - 1}→{frame}", "reference noise FLIP", "SVGF ms", "frame ms", "OIDN aux ms (CPU)"],
        [[r["case"], r["eye"], r["flicker_svgf_flip"], r["flicker_raw_flip"], r["flicker_oidn_aux_flip"],
          r["flicker_reference_flip"], r["svgf_ms"], r["frame_ms"], r["oidn_aux_ms"]] for r in rows]))
    md.append("")
    md.append("## Definitions")
    md.append("")
    md.append("- **bias**: mean luminance (Rec. 709 Y of linear radiance) of the image / of the reference − 1, in %.")
    md.append("- **PSNR**: linear radiance, both images clamped to [0, peak] per channel, "
              "10 log10(peak² / MSE) over all pixels and channels; peak = the reference's 99.9th percentile "
              "luminance (`psnr_peak` in the CSV).")
    md.append("- **FLIP**: mean LDR-FLIP (NVIDIA flip-evaluator, 67 pixels per degree) of the sRGB images "
              "(exposure 1, clamped to [0, 1], sRGB-encoded as the PNGs are).")
    md.append("- **OIDN**: Intel Open Image Denoise (pyoidn, filter RT, HDR, quality high) on the raw "
              "(`--no-denoise`) frame: colour only, and with `render --aov` albedo + normal (cleanAux: they come "
              "from each pixel's G-buffer ray). A ceiling for a single-frame denoiser, on this machine's CPU "
              "(OIDN aux ms: one eye, after a warm-up call).")
    md.append(f"- **flicker**: mean FLIP between frames {frame - 1} and {frame} of the same method. "
              f"**reference noise**: FLIP between the still camera's frame {frame - 1} and {frame} "
              "references (one view, two independent sample streams): what the references' own noise scores; "
              "n/a for the moving camera.")
    md.append("- **SVGF ms**: per frame after the first, the slowest device's device time in stages 6 (SVGF) and "
              "7 (its history copies) from `render --report`; the median. **frame ms**: the median wall time of "
              "those frames.")
    md.append("")
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write("\n".join(md))


def main(argv):
    if len(argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    out, cases_tsv, frame = argv[1], argv[2], int(argv[3])
    params = {}
    machine = os.path.join(out, "machine.txt")
    if os.path.isfile(machine):
        params = dict(line.split("=", 1) for line in open(machine).read().splitlines() if "=" in line)
    with open(cases_tsv) as f:
        cases = [line.rstrip("\n").split("\t") for line in f if line.strip()]
    rows, oidn_ms = [], []
    try:
        if pyoidn is not None:  # a warm-up call: the first one loads the library and its weights
            oidn(np.zeros((8, 8, 3), np.float32), np.zeros((8, 8, 3), np.float32), np.zeros((8, 8, 3), np.float32))
        for row in cases:
            if len(row) != 9:
                raise EvalError(f"{cases_tsv}: a line with {len(row)} fields, expected 9")
            start = len(oidn_ms)
            case_rows = evaluate_case(out, row, frame, oidn_ms)
            for r, ms in zip(case_rows, oidn_ms[start:]):
                r["oidn_aux_ms"] = fmt(ms, 1)
            rows += case_rows
            print(f"[evaluate_denoiser] {row[0]}: " + ", ".join(
                f"{r['eye']} SVGF {r['svgf_psnr_db']} dB / FLIP {r['svgf_flip']}" for r in case_rows), file=sys.stderr)
    except EvalError as e:
        print(f"evaluate_denoiser: error: {e}", file=sys.stderr)
        return 1
    with open(os.path.join(out, "results.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    summary(out, rows, frame, params)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
