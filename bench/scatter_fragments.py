#!/usr/bin/env python3
"""A scan with floaters: MESH plus N small fragments scattered around it (benchmark input, BENCHMARKS.md "Many
charts").

Real scans carry hundreds or thousands of small disconnected pieces (noise, spray, bits of the background).
Each becomes one or more charts of a multi-chart geometry image, and the packer's cost grows with them. This
writes MESH with N fragments in and around its bounding box (12 % margin), cycling through three kinds: a
closed tetrahedron, a single triangle, and an open 4 × 3 vertex strip with a little height noise; each about
0.2–0.6 % of the bounding-box diagonal. The positions come from a seeded generator (--seed): the same
arguments give the same file. Needs numpy; MESH is read through `gimforge convert-format` (any format it
reads).

    bench/scatter_fragments.py tests/data/kitten.ply /tmp/kitten_1000.ply 1000
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_GIMFORGE = os.path.join(HERE, "..", "build", "gimforge")


def read_binary_ply(path):
    """Vertices (n × 3 float64) and triangles (m × 3) of a binary PLY written by `gimforge convert-format`."""
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii")
    nv = int(re.search(r"element vertex (\d+)", header).group(1))
    nf = int(re.search(r"element face (\d+)", header).group(1))
    kind = "<f8" if "property double x" in header else "<f4"
    size = np.dtype(kind).itemsize
    v = np.frombuffer(data, dtype=kind, count=nv * 3, offset=end).reshape(nv, 3).astype(np.float64)
    faces = np.frombuffer(data, dtype=np.dtype([("n", "u1"), ("i", "<i4", 3)]), count=nf, offset=end + nv * 3 * size)
    if not (faces["n"] == 3).all():
        sys.exit(f"{path}: expected triangles only")
    return v, faces["i"].astype(np.int64)


def fragment(kind, centre, size, rng):
    if kind == 0:  # a closed tetrahedron
        p = centre + size * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
        return p, np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    if kind == 1:  # a single triangle
        return centre + size * rng.standard_normal((3, 3)), np.array([[0, 1, 2]])
    grid = np.array([[x, y, 0.1 * rng.standard_normal()] for y in range(3) for x in range(4)], float)
    faces = []
    for y in range(2):
        for x in range(3):
            a = y * 4 + x
            faces += [[a, a + 1, a + 5], [a, a + 5, a + 4]]
    return centre + size * grid, np.array(faces)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("out", help="the PLY to write (ASCII, double coordinates)")
    ap.add_argument("count", type=int, help="fragments to add")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--gimforge", default=DEFAULT_GIMFORGE)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        plain = os.path.join(work, "mesh.ply")
        subprocess.run([a.gimforge, "-q", "convert-format", a.mesh, "-o", plain], check=True, stdout=subprocess.DEVNULL)
        v, f = read_binary_ply(plain)
    rng = np.random.default_rng(a.seed)
    lo, hi = v.min(0), v.max(0)
    diagonal = np.linalg.norm(hi - lo)
    vertices, faces, base = [v], [f], len(v)
    for i in range(a.count):
        centre = lo + rng.random(3) * (hi - lo) * 1.2 - 0.1 * (hi - lo)
        p, t = fragment(i % 3, centre, diagonal * 0.004 * (0.5 + rng.random()), rng)
        vertices.append(p)
        faces.append(t + base)
        base += len(p)
    v, f = np.vstack(vertices), np.vstack(faces)
    with open(a.out, "w") as out:
        out.write("ply\nformat ascii 1.0\nelement vertex %d\nproperty double x\nproperty double y\n"
                  "property double z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n"
                  % (len(v), len(f)))
        for p in v:
            out.write("%.17g %.17g %.17g\n" % tuple(p))
        for t in f:
            out.write("3 %d %d %d\n" % tuple(t))
    print(f"{a.out}: {len(v)} vertices, {len(f)} faces, {a.count} fragments added")


if __name__ == "__main__":
    main()
