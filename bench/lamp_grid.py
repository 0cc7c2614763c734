#!/usr/bin/env python3
# bench/lamp_grid.py: writes lamps.{obj,mtl,json} in the current directory (docs/measurements.md, "Light tree").
# An 8 x 8 grid of 4 x 3 x 4 rooms joined by doors, 16 small ceiling lamps in each (1024 lamps, 2048 emissive triangles).
import random
random.seed(1)
N, S, H = 8, 4.0, 3.0
v, f, out = [], [], []
def quad(a, b, c, d, m):
    base = len(v) + 1
    v.extend([a, b, c, d]); f.append((m, base))
mats = ["wall"] + ["lamp%d" % i for i in range(4)]
for i in range(N):
    for j in range(N):
        x0, z0 = i * S, j * S
        quad((x0, 0, z0), (x0, 0, z0 + S), (x0 + S, 0, z0 + S), (x0 + S, 0, z0), "wall")  # floor
        quad((x0, H, z0), (x0 + S, H, z0), (x0 + S, H, z0 + S), (x0, H, z0 + S), "wall")  # ceiling
        for a in range(4):
            for b in range(4):
                cx, cz, r = x0 + 0.5 + a, z0 + 0.5 + b, 0.1
                y = H - 0.01
                quad((cx - r, y, cz - r), (cx + r, y, cz - r), (cx + r, y, cz + r), (cx - r, y, cz + r), "lamp%d" % random.randrange(4))
# walls at x = k S and z = k S, each room side with a 1 m wide, 2 m high door in its middle
for k in range(N + 1):
    for j in range(N):
        for axis in "xz":
            c, t0 = k * S, j * S
            door = 0 < k < N
            segs = [(t0, t0 + S / 2 - 0.5, 0, H), (t0 + S / 2 + 0.5, t0 + S, 0, H)] if door else [(t0, t0 + S, 0, H)]
            if door: segs.append((t0 + S / 2 - 0.5, t0 + S / 2 + 0.5, 2.0, H))
            for (a, b, y0, y1) in segs:
                P = (lambda t, y: (c, y, t)) if axis == "x" else (lambda t, y: (t, y, c))
                quad(P(a, y0), P(b, y0), P(b, y1), P(a, y1), "wall")
with open("lamps.obj", "w") as o:
    o.write("mtllib lamps.mtl\n")
    for p in v: o.write("v %g %g %g\n" % p)
    cur = None
    for m, b in f:
        if m != cur: o.write("usemtl %s\n" % m); cur = m
        o.write("f %d %d %d\nf %d %d %d\n" % (b, b + 1, b + 2, b, b + 2, b + 3))
with open("lamps.mtl", "w") as o:
    o.write("newmtl wall\nKd 0.7 0.7 0.7\n")
    for i, ke in enumerate([(20, 18, 15), (10, 10, 10), (30, 25, 20), (5, 6, 8)]):
        o.write("newmtl lamp%d\nKd 0 0 0\nKe %g %g %g\n" % ((i,) + ke))
with open("lamps.json", "w") as o:
    o.write('{"mesh": "lamps.obj", "camera": {"position": [1.0, 1.6, 1.0], "target": [6.0, 1.2, 6.0], "vfov_deg": 70}}\n')
