#!/usr/bin/python3
"""What a run holds resident at each step of its start: runs a command (a `parallax render` as a
rule), reads /proc/PID/smaps every --every seconds beside the lines the run writes to stderr, and
prints, for each step, its highest resident set with what made it up: the large anonymous blocks
(resident / mapped MiB each, 8 MiB and more: the scene's arrays), smaller anonymous memory, the
malloc heap, the pages of LLVM (PoCL's compiler) and those of every other file (the program, the
image codec's libraries).

The steps follow the log lines of `render`: load (to "[scene] NAME: N triangles"), tree (the
shading records and the BVH build, to "[bvh] N nodes"), layout (validation, the device set and
the device layout, to "[devices]"), frame (the frames, to the end). A sample every 20 ms misses
a short spike of a few MiB: /usr/bin/time -v gives the exact highest point of the whole run.

Usage: bench/start_memory.py [--every 0.02] [--trace FILE] -- COMMAND...
Example (docs/measurements.md, "What is resident at each highest point"):
  PARALLAX_BVH_CACHE=off bench/start_memory.py -- build/parallax render --scene \\
      build/scale-series/heightfield-smooth-3998792.json --frames 1 --spp 1 --devices 2 \\
      --width 320 --height 180 --no-denoise --overwrite --out /tmp/out
"""
import argparse
import re
import subprocess
import sys
import threading
import time

MAPPING = re.compile(r"^([0-9a-f]+)-([0-9a-f]+) \S+ \S+ \S+ \S+\s*(.*)$")


def snapshot(pid):
    """(total MiB, {kind: MiB}, ["resident/mapped" of each anonymous block of 8 MiB and more])."""
    kinds = {"anon": 0, "heap": 0, "llvm": 0, "files": 0}
    blocks = []
    name, size = "", 0
    with open(f"/proc/{pid}/smaps") as f:
        for line in f:
            m = MAPPING.match(line)
            if m:
                name, size = m.group(3), (int(m.group(2), 16) - int(m.group(1), 16)) >> 20
                continue
            if not line.startswith("Rss:"):
                continue
            kib = int(line.split()[1])
            if not name and kib >= 8192:
                blocks.append((kib >> 10, size))
            elif not name or (name.startswith("[") and name != "[heap]"):
                kinds["anon"] += kib
            elif name == "[heap]":
                kinds["heap"] += kib
            elif "LLVM" in name or "clang" in name:
                kinds["llvm"] += kib
            else:
                kinds["files"] += kib
    total = (sum(kinds.values()) >> 10) + sum(r for r, _ in blocks)
    return total, {k: v >> 10 for k, v in kinds.items()}, sorted(blocks, reverse=True)


def step_after(line, step):
    if step == "load" and line.startswith("[scene]") and " triangles, " in line:
        return "tree"
    if step == "tree" and line.startswith("[bvh]") and " nodes, " in line:
        return "layout"
    if step in ("tree", "layout") and line.startswith("[devices]"):
        return "frame"
    return step


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--every", type=float, default=0.02, help="seconds between samples")
    ap.add_argument("--trace", help="also write every sample and log line, timed, to this file")
    ap.add_argument("command", nargs=argparse.REMAINDER)
    a = ap.parse_args()
    cmd = a.command[1:] if a.command[:1] == ["--"] else a.command
    if not cmd:
        ap.error("no command to run")
    t0 = time.time()
    run = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    state = {"step": "load"}
    highest, events, lock = {}, [], threading.Lock()

    def sample():
        while run.poll() is None:
            try:
                total, kinds, blocks = snapshot(run.pid)
            except (OSError, ValueError):
                break
            with lock:
                step = state["step"]
                events.append((time.time() - t0, f"{total} MiB {kinds} {blocks}"))
                if total > highest.get(step, (0,))[0]:
                    highest[step] = (total, kinds, blocks, time.time() - t0)
            time.sleep(a.every)

    sampler = threading.Thread(target=sample)
    sampler.start()
    for line in run.stderr:
        with lock:
            events.append((time.time() - t0, line.rstrip()))
            state["step"] = step_after(line, state["step"])
    run.wait()
    sampler.join()
    if a.trace:
        with open(a.trace, "w") as f:
            for t, what in events:
                f.write(f"{t:8.3f} {what}\n")
    print(f"{'step':8s} {'MiB':>6s}  at s   heap  anon  llvm  files  large blocks (resident/mapped MiB)")
    for step in ("load", "tree", "layout", "frame"):
        if step in highest:
            total, k, blocks, t = highest[step]
            big = ", ".join(f"{r}/{m}" for r, m in blocks)
            print(f"{step:8s} {total:6d} {t:5.1f} {k['heap']:6d} {k['anon']:5d} {k['llvm']:5d} {k['files']:6d}  {big}")
    return run.returncode


if __name__ == "__main__":
    sys.exit(main())
