#!/usr/bin/env python3
"""Writes meshes that are not oriented 2-manifolds, for the multi-chart input cut (docs/multichart.md,
"Input"; BENCHMARKS.md, "Non-manifold and misoriented inputs"):

  boxes_line.obj     two closed boxes (subdivided 4 x 4 per side) sharing a line of four edges
  sphere_fins0.obj   an icosphere with three zero-area fins (third corner on the edge) on one edge
  sphere_flip90.obj  an icosphere with 90 % of its faces reversed (closed, mostly inside out)
  moebius.obj        a Moebius band of 200 x 20 quads
  torus_fins.ply     a 320 x 320 torus (204,800 faces) with 300 fins on scattered edges and a 40 x 40
                     patch of reversed faces, binary PLY

Usage: bench/defect_meshes.py OUTDIR
"""
import math
import os
import random
import struct
import sys


def write_obj(path, vertices, faces):
    with open(path, "w") as out:
        for v in vertices:
            out.write("v %.17g %.17g %.17g\n" % v)
        for f in faces:
            out.write("f %d %d %d\n" % tuple(i + 1 for i in f))


def write_ply(path, vertices, faces):
    with open(path, "wb") as out:
        out.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty double x\nproperty double y\n"
                   "property double z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n"
                   % (len(vertices), len(faces))).encode())
        out.write(b"".join(struct.pack("<3d", *v) for v in vertices))
        out.write(b"".join(struct.pack("<B3i", 3, *f) for f in faces))


def icosphere(levels):
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [tuple(c / math.sqrt(sum(x * x for x in p)) for c in p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid = {}

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = [(v[a][i] + v[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(x * x for x in p))
                v.append(tuple(x / n for x in p))
                mid[key] = len(v) - 1
            return mid[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return v, f


def box(origin, n, vertices, faces, index):
    """A closed unit box of n x n quads per side at `origin`, outward; `index` welds equal positions."""
    def vid(p):
        key = tuple(round(c * n) for c in p)
        if key not in index:
            index[key] = len(vertices)
            vertices.append(tuple(float(c) for c in p))
        return index[key]
    ox, oy, oz = origin
    for axis in range(3):
        for side in (0, 1):
            for i in range(n):
                for j in range(n):
                    def corner(a, b):
                        p = [0.0, 0.0, 0.0]
                        p[axis] = side
                        p[(axis + 1) % 3] = a / n
                        p[(axis + 2) % 3] = b / n
                        return vid((ox + p[0], oy + p[1], oz + p[2]))
                    q = [corner(i, j), corner(i + 1, j), corner(i + 1, j + 1), corner(i, j + 1)]
                    if side == 0:
                        q.reverse()
                    faces.append((q[0], q[1], q[2]))
                    faces.append((q[0], q[2], q[3]))


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    rnd = random.Random(3)

    vertices, faces, index = [], [], {}
    box((0, 0, 0), 4, vertices, faces, index)
    box((1, 1, 0), 4, vertices, faces, index)  # its edge (1,1,z) lies on the first box's
    write_obj(os.path.join(out, "boxes_line.obj"), vertices, faces)

    v, f = icosphere(3)
    a, b, _ = f[0]
    for k in range(3):  # third corners on the edge's line: no area
        s = 0.25 * (k + 1)
        v.append(tuple(v[a][i] + s * (v[b][i] - v[a][i]) for i in range(3)))
        f.append((a, b, len(v) - 1))
    write_obj(os.path.join(out, "sphere_fins0.obj"), v, f)

    v, f = icosphere(3)
    f = [(x, z, y) if rnd.random() < 0.9 else (x, y, z) for x, y, z in f]
    write_obj(os.path.join(out, "sphere_flip90.obj"), v, f)

    nu, nv = 200, 20
    v, f = [], []
    for i in range(nu):
        t = 2 * math.pi * i / nu
        for j in range(nv + 1):
            s = -0.3 + 0.6 * j / nv
            v.append(((1 + s * math.cos(t / 2)) * math.cos(t), (1 + s * math.cos(t / 2)) * math.sin(t), s * math.sin(t / 2)))
    idx = lambda i, j: (0 * (nv + 1) + (nv - j)) if i == nu else i * (nv + 1) + j
    for i in range(nu):
        for j in range(nv):
            p, q, r, s = idx(i, j), idx(i, j + 1), idx(i + 1, j), idx(i + 1, j + 1)
            f += [(p, r, s), (p, s, q)]
    write_obj(os.path.join(out, "moebius.obj"), v, f)

    nu = nv = 320
    big_r, small_r = 3.0, 1.0
    v = [((big_r + small_r * math.cos(2 * math.pi * j / nv)) * math.cos(2 * math.pi * i / nu),
          (big_r + small_r * math.cos(2 * math.pi * j / nv)) * math.sin(2 * math.pi * i / nu),
          small_r * math.sin(2 * math.pi * j / nv)) for i in range(nu) for j in range(nv)]
    at = lambda i, j: (i % nu) * nv + (j % nv)
    f = []
    for i in range(nu):
        for j in range(nv):
            f += [(at(i, j), at(i + 1, j), at(i + 1, j + 1)), (at(i, j), at(i + 1, j + 1), at(i, j + 1))]
    for i in range(20, 60):
        for j in range(10, 50):
            for k in (0, 1):
                x, y, z = f[2 * (i * nv + j) + k]
                f[2 * (i * nv + j) + k] = (x, z, y)
    for _ in range(300):
        x, y, _ = f[rnd.randrange(len(f))]
        m = [(v[x][i] + v[y][i]) / 2 for i in range(3)]
        n = math.sqrt(sum(c * c for c in m))
        v.append(tuple(c * (1 + 0.02 / n) for c in m))
        f.append((x, y, len(v) - 1))
    write_ply(os.path.join(out, "torus_fins.ply"), v, f)


if __name__ == "__main__":
    main()
