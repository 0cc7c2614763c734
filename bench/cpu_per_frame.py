#!/usr/bin/env python3
"""CPU time per frame of `parallax render`, for comparing builds or flags on a machine that other
work shares: the wall time of a frame swings with the load, the process's own CPU time much less.
Per run: user + system seconds of a render of F + 2 frames less those of a 2-frame render (so that
start-up, kernel builds and the first frame cancel), over F. Runs alternate between the commands
(A, B, A, B, ...); prints the median and range per command.

  bench/cpu_per_frame.py [--runs 3] [--frames 15] --cmd "build/parallax" --cmd "old/parallax" \\
      -- --scene rooms --width 320 --height 180 --devices 2 --no-denoise

A --cmd may carry flags of its own ("build/parallax --direct-light tree"); the flags after -- go to
every render. Each render writes into a temporary folder that is removed afterwards. A binary that
has --kernel-build gets `--kernel-build optimized`, unless the flags name one: `auto` could build the
short run's kernels quickly and the long run's optimised, and the subtraction would then mix the two.
"""
import argparse
import functools
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile


@functools.lru_cache(maxsize=None)
def takes_kernel_build(binary):
    """Whether `binary render` has --kernel-build (asked once per binary, not per run)."""
    help_text = subprocess.run([binary, "render", "--help"], capture_output=True, text=True).stdout
    return "--kernel-build" in help_text


def build_flags(binary, flags):
    """`--kernel-build optimized` where `binary` takes it and `flags` name no build."""
    if any(f.startswith("--kernel-build") for f in flags):
        return []
    return ["--kernel-build", "optimized"] if takes_kernel_build(binary) else []


def cpu_seconds(cmd, flags, frames, out):
    shutil.rmtree(out, ignore_errors=True)
    args = shlex.split(cmd)
    flags = flags + build_flags(args[0], args[1:] + flags)
    p = subprocess.Popen([args[0], "render"] + args[1:] + flags + ["--frames", str(frames), "--out", out],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(p.pid, 0)
    if status != 0:
        sys.exit(f"cpu_per_frame: `{cmd}` failed: {p.stderr.read().decode(errors='replace')[-400:]}")
    return usage.ru_utime + usage.ru_stime


def main():
    argv = sys.argv[1:]
    flags = []
    if "--" in argv:
        flags = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cmd", action="append", required=True, help="a parallax binary, with flags of its own")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--frames", type=int, default=15, help="frames measured per run (default 15)")
    a = ap.parse_args(argv)
    if a.runs < 1 or a.frames < 1:
        sys.exit("cpu_per_frame: --runs and --frames must be at least 1")
    per = {c: [] for c in a.cmd}
    with tempfile.TemporaryDirectory(prefix="cpu-per-frame-") as tmp:
        out = os.path.join(tmp, "out")
        for r in range(a.runs):
            for c in a.cmd:
                long_run = cpu_seconds(c, flags, a.frames + 2, out)
                short_run = cpu_seconds(c, flags, 2, out)
                per[c].append((long_run - short_run) / a.frames * 1000.0)
            print(f"cpu_per_frame: run {r + 1}/{a.runs} done", file=sys.stderr)
    first = statistics.median(per[a.cmd[0]])
    for c in a.cmd:
        m = statistics.median(per[c])
        print(f"{c}: {m:.1f} CPU ms per frame [{min(per[c]):.1f}-{max(per[c]):.1f}], x{m / first:.3f} the first")


if __name__ == "__main__":
    main()
