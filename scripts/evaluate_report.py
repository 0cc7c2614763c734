#!/usr/bin/python3
"""Plots and summary.md for scripts/evaluate, from the CSVs the benches wrote into OUT.

Usage: /usr/bin/python3 scripts/evaluate_report.py OUT

Runs with Debian's python3-matplotlib and python3-numpy. Every speed figure it prints is set
beside its error against a converged reference, and our figures beside the paper's.
"""
import csv
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# The paper's figures: 4x RTX A6000, 2x1280x720, 1 spp, 6 bounces.
PAPER = {
    "setup": "4x RTX A6000, 2x1280x720 (both eyes), 1 spp, 6 bounces",
    "speedup_mean": 2.25,
    "speedup_scenes": {"San Miguel": 1.83, "Sponza": 2.80, "Bistro": 2.11},
    "stage_speedup": {"reprojection": 2.75, "hole filling": 2.89, "denoising": 4.2},
    "hz": "~120 Hz (animated San Miguel)",
    "seam_psnr": "19.9-21.97 dB (1 spp + SVGF vs a 4096 spp reference)",
    "seam_cost": "0.2-0.9 dB",
}
STAGE_ORDER = [2, 12, 3, 4, 5, 6, 7, 8, 9]
# Paper stage names for the per-stage speed-up: our stage numbers.
PAPER_STAGES = {"reprojection": [4], "hole filling": [5], "denoising": [6, 7]}
PIPELINES = ["proposed", "baseline", "mono"]
MODES = ["1 device", "independent", "bilateral", "halo"]


def read_csv(path):
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def read_kv(path):
    kv = {}
    if os.path.exists(path):
        for line in open(path):
            if "=" in line:
                k, v = line.rstrip("\n").split("=", 1)
                kv[k] = v
    return kv


def num(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def fmt(v, digits=2):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "identical"
    return f"{v:.{digits}f}"


def ordered(values, order):
    return [v for v in order if v in values] + sorted(v for v in values if v not in order)


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def savefig(fig, out, name):
    path = os.path.join(out, name)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return name


def main(out):
    machine = read_kv(os.path.join(out, "machine.txt"))
    devices_txt = open(os.path.join(out, "devices.txt")).read().strip() if os.path.exists(
        os.path.join(out, "devices.txt")) else "(not recorded)"
    stages = read_csv(os.path.join(out, "pipelines_stages.csv"))
    makespan = read_csv(os.path.join(out, "pipelines_makespan.csv"))
    frames = read_csv(os.path.join(out, "pipelines_frames.csv"))
    seams = read_csv(os.path.join(out, "seams.csv"))
    seam_frames = read_csv(os.path.join(out, "seams_frames.csv"))
    speed = read_csv(os.path.join(out, "speed_error.csv"))
    missing = [n for n, rows in [("pipelines_stages.csv", stages), ("pipelines_makespan.csv", makespan),
                                 ("seams.csv", seams), ("speed_error.csv", speed)] if not rows]
    if missing:
        sys.exit("evaluate_report: missing or empty: " + ", ".join(missing))

    scenes = list(dict.fromkeys(r["scene"] for r in makespan))
    ref_spp = machine.get("ref_spp", "?")
    md = []
    figs = {}

    # ---------------- Table 1: per-stage device times ----------------
    st = {}  # (scene, pipeline, stage, device) -> ms
    owner = {}
    stage_names = {}
    for r in stages:
        key = (r["scene"], r["pipeline"], int(r["stage"]), int(r["device"]))
        st[key] = num(r["median_device_ms"])
        stage_names[int(r["stage"])] = r["stage_name"]
        if r.get("owner") == "1":
            owner[(r["scene"], r["pipeline"])] = int(r["device"])
    ndev = max(int(r["device"]) for r in stages) + 1

    fig, axes = plt.subplots(len(scenes), 1, figsize=(10, 3.6 * len(scenes)), squeeze=False)
    for ax, scene in zip(axes[:, 0], scenes):
        present = [s for s in STAGE_ORDER if any(k[0] == scene and k[1] != "mono" and k[2] == s for k in st)]
        x = np.arange(len(present))
        bars = [(p, d) for p in ("proposed", "baseline") for d in range(ndev)]
        width = 0.8 / max(1, len(bars))
        for i, (p, d) in enumerate(bars):
            vals = [st.get((scene, p, s, d), 0.0) for s in present]
            mark = " (owner)" if owner.get((scene, p)) == d else ""
            ax.bar(x + (i - (len(bars) - 1) / 2) * width, vals, width, label=f"{p} d{d}{mark}",
                   hatch="//" if p == "baseline" else None, alpha=0.9)
        ax.set_xticks(x)
        ax.set_xticklabels([f"{s} {stage_names.get(s, '')}" for s in present], rotation=25, ha="right", fontsize=8)
        ax.set_yscale("log")  # stages differ by orders of magnitude (denoising vs reprojection)
        ax.set_ylabel("median device ms / frame")
        ax.set_title(f"Table 1, {scene}: per-stage device time, proposed vs baseline")
        ax.legend(fontsize=7, ncol=2)
    figs["table1"] = savefig(fig, out, "table1_stage_times.png")

    # ---------------- Table 2: makespan ----------------
    mk = {(r["scene"], r["pipeline"]): r for r in makespan}
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    pipes = ordered({r["pipeline"] for r in makespan}, PIPELINES)
    x = np.arange(len(scenes))
    width = 0.8 / len(pipes)
    for i, p in enumerate(pipes):
        axes[0].bar(x + (i - (len(pipes) - 1) / 2) * width, [num(mk[(s, p)]["makespan_ms"]) if (s, p) in mk else 0
                                                             for s in scenes], width, label=p)
    axes[0].set_xticks(x)
    axes[0].set_xticklabels(scenes)
    axes[0].set_ylabel("makespan ms (timed frames)")
    axes[0].set_title("Table 2: makespan over the camera animation")
    axes[0].legend(fontsize=8)
    for scene in scenes:
        for p in pipes:
            ys = [num(r["wall_ms"]) for r in frames if r["scene"] == scene and r["pipeline"] == p]
            if ys:
                axes[1].plot([int(r["frame"]) for r in frames if r["scene"] == scene and r["pipeline"] == p], ys,
                             marker=".", label=f"{scene} {p}")
    axes[1].set_xlabel("frame")
    axes[1].set_ylabel("wall ms")
    axes[1].set_title("frame time along the animation")
    axes[1].legend(fontsize=7)
    figs["table2"] = savefig(fig, out, "table2_makespan.png")

    # ---------------- Table 3 / Fig. 5: seams ----------------
    fig, axes = plt.subplots(len(scenes), 2, figsize=(11, 3.4 * len(scenes)), squeeze=False)
    for row, scene in enumerate(scenes):
        rows = [r for r in seam_frames if r["scene"] == scene]
        for m in ordered({r["mode"] for r in rows}, MODES):
            rr = [r for r in rows if r["mode"] == m]
            fr = [int(r["frame"]) for r in rr]
            if m != "1 device":  # one device has no seam: its band is measured at the same rows
                axes[row, 0].plot(fr, [num(r["seam_band_psnr_db"]) for r in rr], marker="o", label=m)
            else:
                axes[row, 0].plot(fr, [num(r["seam_band_psnr_db"]) for r in rr], "k--", marker="x", label="1 device (no seam)")
            axes[row, 1].plot(fr, [num(r["cambi"]) for r in rr], marker="o", label=m)
        axes[row, 0].set_title(f"Fig. 5, {scene}: PSNR of 8-row bands at the seams")
        for ax in axes[row]:
            ax.xaxis.get_major_locator().set_params(integer=True)
        axes[row, 0].set_xlabel("frame")
        axes[row, 0].set_ylabel("dB vs reference")
        axes[row, 0].legend(fontsize=7)
        axes[row, 1].set_title(f"{scene}: CAMBI (whole image, ours)")
        axes[row, 1].set_xlabel("frame")
        axes[row, 1].set_ylabel("CAMBI")
        axes[row, 1].legend(fontsize=7)
    figs["fig5"] = savefig(fig, out, "fig5_seam_psnr.png")

    # Seam crops: the rows around the seams of each mode's last frame, left eye, enlarged.
    crops = []
    for i, scene in enumerate(scenes):
        folder = os.path.join(out, "images", str(i))
        files = [("reference", "reference.png"), ("1 device", "single.png"), ("independent", "independent.png"),
                 ("bilateral", "bilateral.png"), ("halo", "halo.png")]
        files = [(n, os.path.join(folder, f)) for n, f in files if os.path.exists(os.path.join(folder, f))]
        if files:
            crops.append((scene, files))
    if crops:
        fig, axes = plt.subplots(len(crops), len(crops[0][1]), figsize=(3.2 * len(crops[0][1]), 2.4 * len(crops)),
                                 squeeze=False)
        for row, (scene, files) in enumerate(crops):
            for col, (name, path) in enumerate(files):
                img = mpimg.imread(path)
                ax = axes[row, col]
                ax.imshow(img[:, : img.shape[1] // 2], interpolation="nearest")  # left eye
                h = img.shape[0]
                for k in range(1, ndev):  # where the strips meet (split_rows: remainders to the top)
                    ax.axhline(k * h // ndev + min(k, h % ndev) - 0.5, color="red", lw=0.5, alpha=0.6)
                ax.set_title(f"{scene}: {name}", fontsize=8)
                ax.axis("off")
        figs["crops"] = savefig(fig, out, "seam_images.png")

    # ---------------- speed vs error ----------------
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    for scene in ordered({r["scene"] for r in speed}, scenes):
        rr = sorted((r for r in speed if r["scene"] == scene), key=lambda r: int(r["spp"]))
        t = [num(r["wall_ms"]) for r in rr]
        axes[0].loglog(t, [num(r["rel_mse"]) for r in rr], marker="o", label=scene)
        axes[1].semilogx(t, [num(r["psnr_db"]) for r in rr], marker="o", label=scene)
        for r, tt in zip(rr, t):
            axes[0].annotate(r["spp"] + " spp", (tt, num(r["rel_mse"])), fontsize=7)
    axes[0].set_xlabel("ms per stereo frame (wall, median)")
    axes[0].set_ylabel("relMSE vs reference")
    axes[1].set_xlabel("ms per stereo frame (wall, median)")
    axes[1].set_ylabel("PSNR dB vs reference")
    axes[0].set_title("speed vs error (path tracing only)")
    axes[1].set_title("speed vs PSNR")
    axes[0].legend(fontsize=8)
    figs["speed"] = savefig(fig, out, "speed_vs_error.png")

    # ---------------- Fig. 4: the control loop ----------------
    control = None
    control_path = os.path.join(out, "control_report.json")
    if os.path.exists(control_path):
        control = json.load(open(control_path))
        cf = control["frames"]
        lo, hi = (float(x) for x in control["target_ms"].split(":"))
        f_idx = [r["frame"] for r in cf]
        fig, ax = plt.subplots(figsize=(8, 3.6))
        ax.axhspan(lo, hi, color="tab:green", alpha=0.15, label=f"window {lo:g}-{hi:g} ms")
        ax.plot(f_idx, [r["wall_ms"] for r in cf], marker="o", color="tab:blue", label="frame time (wall)")
        pred = [(r["frame"], r["predicted_ms"]) for r in cf if r.get("predicted_ms") is not None]
        if pred:
            ax.plot([p[0] for p in pred], [p[1] for p in pred], ls="--", color="tab:gray", label="predicted")
        ax.set_xlabel("frame (frame 0 compiles the kernels)")
        ax.set_ylabel("ms per stereo frame")
        ax.set_ylim(0, max(2 * hi, max(r["wall_ms"] for r in cf[1:]) * 1.1 if len(cf) > 1 else 2 * hi))
        ax2 = ax.twinx()
        ax2.step(f_idx, [r["spp"] for r in cf], where="post", color="tab:red", label="spp")
        ax2.set_ylabel("spp", color="tab:red")
        ax.legend(loc="upper left", fontsize=8)
        ax.set_title("Fig. 4: control loop (" + control["scene"] + ")")
        figs["fig4"] = savefig(fig, out, "fig4_control_loop.png")

    # ---------------- figures beside the paper ----------------
    speedups = {s: num(mk[(s, "baseline")]["makespan_ms"]) / num(mk[(s, "proposed")]["makespan_ms"])
                for s in scenes if (s, "baseline") in mk and (s, "proposed") in mk}

    def stage_speedup(scene, ours):
        # The baseline runs the stage on the owner alone; the proposed pipeline on every device
        # at once, so its stage takes as long as its slowest device.
        base = sum(st.get((scene, "baseline", s, d), 0.0) for s in ours for d in range(ndev))
        prop = max((sum(st.get((scene, "proposed", s, d), 0.0) for s in ours) for d in range(ndev)), default=0.0)
        return base / prop if prop > 0 and base > 0 else float("nan")

    seam_last = {}  # (scene, mode) -> row of device 0
    for r in seams:
        seam_last.setdefault((r["scene"], r["mode"]), r)
    band = {k: num(r["seam_band_psnr_db"]) for k, r in seam_last.items()}
    seam_modes = [m for m in ("independent", "bilateral", "halo")]
    band_vals = [band[(s, m)] for s in scenes for m in seam_modes if (s, m) in band]
    costs = [band[(s, "1 device")] - band[(s, m)] for s in scenes for m in ("independent", "bilateral")
             if (s, m) in band and (s, "1 device") in band]

    def rng(vals, unit=""):
        vals = [v for v in vals if not math.isnan(v) and not math.isinf(v)]
        return f"{min(vals):.2f} to {max(vals):.2f}{unit}" if vals else "-"

    w, h = machine.get("width", "?"), machine.get("height", "?")
    ours_setup = (f"{machine.get('devices', '?')} OpenCL devices, 2x{w}x{h}, 1 spp, 6 bounces, "
                  f"references {ref_spp} spp")
    md.append("# parallax evaluation\n")
    md.append(f"Produced by `{machine.get('command', 'scripts/evaluate')}` on {machine.get('date_utc', '?')} "
              f"(commit {machine.get('git', '?')}).\n")
    md.append("## Machine\n")
    md.append(f"- CPU: {machine.get('cpu', '?')}, {machine.get('cores', '?')} cores visible")
    md.append(f"- Load average (1, 5, 15 min) when the run started: {machine.get('loadavg', '?')}. Other processes "
              "on the same cores slow every figure and take from what parallel devices can gain.")
    md.append(f"- Run: {ours_setup}; {machine.get('frames', '?')} timed frames after {machine.get('warmup', '?')} "
              f"warm-up for Tables 1-2; {machine.get('seam_frames', '?')} frames for the seams; scenes "
              f"{', '.join(scenes)}")
    md.append("- OpenCL devices (`parallax devices`):\n")
    md.append("```\n" + devices_txt + "\n```\n")
    if machine.get("quick") == "1":
        md.append("> **--quick run**: tiny images, few frames and a noisy reference. It checks that the evaluation "
                  "runs end to end; its figures mean little.\n")

    md.append("## Beside the paper\n")
    md.append(f"The paper: {PAPER['setup']}, scenes San Miguel, Sponza, Bistro. Ours: {ours_setup}, on this "
              "machine's devices and our scenes, so only the shape of the figures is comparable, not the values.\n")
    rows = [["speed-up vs baseline, mean (makespan ratio)", f"x{PAPER['speedup_mean']}",
             f"x{np.mean(list(speedups.values())):.2f}" if speedups else "-"]]
    paper_scenes = ", ".join(f"{k} x{v}" for k, v in PAPER["speedup_scenes"].items())
    rows.append(["speed-up per scene", paper_scenes, ", ".join(f"{s} x{v:.2f}" for s, v in speedups.items())])
    for name, paper_v in PAPER["stage_speedup"].items():
        ours = [f"{s} x{stage_speedup(s, PAPER_STAGES[name]):.2f}" for s in scenes]
        rows.append([f"per-stage speed-up: {name}", f"x{paper_v}", ", ".join(ours)])
    hz = ", ".join(f"{s} {num(mk[(s, 'proposed')]['hz']):.1f} Hz" for s in scenes if (s, "proposed") in mk)
    rows.append(["frame rate, proposed", PAPER["hz"], hz])
    rows.append(["seam-band PSNR (independent, bilateral, halo)", PAPER["seam_psnr"],
                 rng(band_vals, " dB") + f" (1 spp + SVGF vs {ref_spp} spp)"])
    rows.append(["what seams cost (1-device band PSNR minus independent/bilateral; > 0 = worse)", PAPER["seam_cost"],
                 rng(costs, " dB")])
    md.append(table(["figure", "paper", "this machine"], rows))
    md.append("\nPer-stage speed-up = the baseline's stage time (owner alone) / the proposed stage's slowest device; "
              "denoising counts stages 6 and 7. Error beside each speed figure: Tables 2 and 3.\n")

    # Table 1
    md.append("## Table 1: per-stage device time (median ms per frame)\n")
    md.append("`*` marks the owner (the device that assembles and shows the frame). Proposed and baseline side by "
              "side; mono for reference.\n")
    for scene in scenes:
        pipes_here = [p for p in PIPELINES if any(k[0] == scene and k[1] == p for k in st)]
        header = ["stage"] + [f"{p[:4]} d{d}{'*' if owner.get((scene, p)) == d else ''}" for p in pipes_here
                              for d in range(ndev)]
        rows = []
        for s in STAGE_ORDER:
            if not any(k[0] == scene and k[2] == s for k in st):
                continue
            rows.append([f"{s} {stage_names.get(s, '')}"] + [fmt(st[(scene, p, s, d)]) if (scene, p, s, d) in st
                                                              else "" for p in pipes_here for d in range(ndev)])
        md.append(f"**{scene}**\n")
        md.append(table(header, rows) + "\n")
    md.append(f"![Table 1]({figs['table1']})\n")

    # Table 2
    md.append("## Table 2: makespan over the camera animation\n")
    rows = []
    for scene in scenes:
        for p in ordered({k[1] for k in mk if k[0] == scene}, PIPELINES):
            r = mk[(scene, p)]
            base = mk.get((scene, "baseline"))
            ratio = num(base["makespan_ms"]) / num(r["makespan_ms"]) if base else float("nan")
            rows.append([scene, p, fmt(num(r["makespan_ms"]), 0), fmt(num(r["median_frame_ms"]), 1),
                         fmt(num(r["hz"]), 1), f"x{ratio:.2f}", f"{100 * num(r['reprojected']):.1f}%",
                         fmt(num(r["right_psnr_db"])), fmt(num(r["right_rel_mse"]), 4),
                         fmt(num(r.get("last_right_psnr_db", "nan"))), fmt(num(r.get("last_right_rel_mse", "nan")), 4)])
    md.append(table(["scene", "pipeline", "makespan ms", "median frame ms", "Hz", "baseline / this",
                     "right eye reprojected", "right-eye PSNR dB", "right-eye relMSE", "last frame PSNR dB",
                     "last frame relMSE"], rows))
    md.append(f"\nError: the right eye (1 spp, denoised) against {ref_spp} spp references of frame 0 (no "
              "denoiser history yet) and of the last frame (with history).\n")
    md.append(f"![Table 2]({figs['table2']})\n")

    # Table 3
    md.append("## Table 3 / Fig. 5: seams\n")
    md.append("Denoising split across devices, per seam mode, at the last frame of the animation. Seam-band PSNR: "
              "8-row bands centred on each seam, both eyes, against the reference. CAMBI: banding over the whole "
              "image as shown in 8 bits (our implementation, `host/image/cambi.h`; lower is better).\n")
    rows = []
    for scene in scenes:
        for m in ordered({k[1] for k in seam_last if k[0] == scene}, MODES):
            rr = [r for r in seams if r["scene"] == scene and r["mode"] == m]
            r = rr[0]
            rows.append([scene, m, " / ".join(fmt(num(x["denoise_ms"])) for x in rr),
                         " / ".join(fmt(num(x["transfer_ms"])) for x in rr), fmt(num(r["psnr_db"])),
                         fmt(num(r["rel_mse"]), 4), fmt(num(r["seam_band_psnr_db"])),
                         fmt(num(r["band_psnr_vs_single_db"])), fmt(num(r["cambi"]), 4),
                         fmt(num(r["reference_cambi"]), 4)])
    md.append(table(["scene", "mode", "denoise ms / device", "transfer ms / device", "PSNR dB", "relMSE",
                     "seam-band PSNR dB", "band vs 1 device dB", "CAMBI", "reference CAMBI"], rows))
    md.append("\n'band vs 1 device': the seam bands against the 1-device denoised image ('identical' = bit-equal).\n")
    md.append(f"![Fig. 5]({figs['fig5']})\n")
    if "crops" in figs:
        md.append("Last frame, left eye, per mode (red lines: where the strips meet):\n")
        md.append(f"![seam images]({figs['crops']})\n")

    # Speed vs error
    md.append("## Speed vs error (path tracing, no denoising)\n")
    rows = [[r["scene"], r["spp"], fmt(num(r["wall_ms"]), 1), fmt(num(r["device_ms"]), 1), fmt(num(r["rel_mse"]), 5),
             fmt(num(r["psnr_db"]))] for r in speed]
    md.append(table(["scene", "spp", "ms / stereo frame (wall)", "ms (slowest device)", "relMSE", "PSNR dB"], rows))
    md.append(f"\n![speed vs error]({figs['speed']})\n")

    if control is not None:
        cf = control["frames"]
        lo, hi = (float(x) for x in control["target_ms"].split(":"))
        after = cf[1:] if len(cf) > 1 else cf
        inside = sum(1 for r in after if lo <= r["wall_ms"] <= hi)
        last = cf[-1]
        md.append("## Fig. 4: the control loop\n")
        md.append(f"`parallax render --target-ms {control['target_ms']}` on {control['scene']}, "
                  f"{len(cf)} frames from 1 spp (the paper's window is 11-20 ms on its GPUs; on this machine the "
                  f"window is set from the measured 1-spp frame time). Frames after the first inside the window: "
                  f"{inside} of {len(after)}. Settled at {last['spp']} spp, {last['bounces']} bounces, "
                  f"{last['svgf_iterations']} SVGF iterations, {fmt(last['wall_ms'], 1)} ms "
                  f"({fmt(1000.0 / last['wall_ms'], 1)} Hz). Paper: frame time held within 11-20 ms at ~3.9 spp.\n")
        md.append(f"![Fig. 4]({figs['fig4']})\n")

    md.append("## Not measured\n")
    md.append("- **FLIP**: no implementation is packaged for Debian bookworm, so no perceptual metric beyond CAMBI "
              "is reported.")
    md.append("- **CAMBI** is our implementation of Tandon et al. (PCS 2021), not libvmaf's (not usable from "
              "Debian's packages on an image in memory): no anti-dithering pre-filter, full-range luma, a "
              "gamma-2.4 display for the visibility of steps, windows scaled to small images, plain mean over 5 "
              "scales. Its values are on its own scale (0 = no banding, at most 1), not libvmaf's 0-24.")
    md.append("- The paper's scenes (San Miguel, Sponza, Bistro) and GPUs: run with `--scenes` pointing at them and "
              "on GPU OpenCL devices to compare values, not only shapes.")
    md.append("")
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write("\n".join(md))


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        sys.exit(__doc__)
    main(sys.argv[1])
