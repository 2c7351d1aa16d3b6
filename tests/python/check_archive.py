#!/usr/bin/env python3
"""Checks that h5py reads a gimforge archive exactly as written.

Usage: check_archive.py WRITER OUT.h5

Runs WRITER (the write_sample_archive executable) to produce OUT.h5, then opens it with h5py and checks
every value, dtype, chunk shape, compression filter and attribute that write_sample_archive.cpp documents.
Exits 1 with a message naming the first mismatch; prints "h5py check passed" when everything matches.
"""
import json
import re
import subprocess
import sys


def fail(message):
    print(f"check_archive.py: FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def expect(condition, message):
    if not condition:
        fail(message)


def expect_equal(what, got, want):
    expect(got == want, f"{what}: got {got!r}, expected {want!r}")


def run_writer(writer, out):
    result = subprocess.run([writer, out], capture_output=True, text=True, check=False)
    expect(result.returncode == 0,
           f"{writer} exited with {result.returncode}: {result.stderr.strip()}")
    expect("HDF5-DIAG" not in result.stderr + result.stdout, f"writer printed HDF5 diagnostics:\n{result.stderr}")


def check_root(f):
    attrs = f.attrs
    expect_equal("/ format", attrs.get("format"), "gimforge")
    version = attrs.get("format_version")
    expect_equal("/ format_version", version, 2)
    expect_equal("/ format_version dtype", getattr(version, "dtype", None), np.dtype("int64"))
    expect(re.fullmatch(r"\d+\.\d+\.\d+.*", attrs.get("gimforge_version", "")),
           f"/ gimforge_version {attrs.get('gimforge_version')!r} is not a version")
    expect(re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", attrs.get("created", "")),
           f"/ created {attrs.get('created')!r} is not ISO-8601 UTC")
    expect("write_sample_archive" in attrs.get("creator", ""), f"/ creator {attrs.get('creator')!r}")
    expect_equal("/ creation_parameters", json.loads(attrs.get("creation_parameters", "null")),
                 {"sample": True, "size": [5, 4]})


def check_dataset(ds, dtype, values, chunks):
    name = ds.name
    expect_equal(f"{name} dtype", ds.dtype, np.dtype(dtype))
    expect_equal(f"{name} shape", ds.shape, values.shape)
    got = ds[()]
    if not np.array_equal(got, values):
        index = tuple(int(i) for i in np.argwhere(got != values)[0])
        fail(f"{name}{list(index)}: got {got[index]!r}, expected {values[index]!r}")
    expect_equal(f"{name} chunks", ds.chunks, chunks)
    expect_equal(f"{name} compression", ds.compression, "gzip")
    expect_equal(f"{name} shuffle", ds.shuffle, True)


def check_sample(f):
    expect("sample" in f, "group /sample is missing")
    g = f["sample"]
    check_dataset(g["image_f32"], "float32", (np.arange(60, dtype=np.float32) * 0.5).reshape(5, 4, 3), (5, 4, 3))
    u16 = g["image_u16"]
    check_dataset(u16, "uint16", (np.arange(16, dtype=np.uint16) * 1000).reshape(4, 4), (4, 4))
    expect_equal("image_u16 scale", float(u16.attrs.get("scale", np.nan)), 0.001)
    expect_equal("image_u16 offset", float(u16.attrs.get("offset", np.nan)), -1.0)
    expect_equal("/sample/names", list(g["names"].asstr()[()]), ["alpha", "beta", "gamma"])
    expect(h5py.check_string_dtype(g["names"].dtype).length is None, "/sample/names is not variable-length")
    expect_equal("/sample/names encoding", h5py.check_string_dtype(g["names"].dtype).encoding, "utf-8")
    expect(isinstance(g.get("nested/deeper"), h5py.Group), "group /sample/nested/deeper is missing")
    expect_equal("/sample/nested/deeper depth", g["nested/deeper"].attrs.get("depth"), 2)
    attrs = g.attrs
    expect_equal("/sample label", attrs.get("label"), "Zürich ✓")
    expect_equal("/sample count", attrs.get("count"), 42)
    expect_equal("/sample ratio", attrs.get("ratio"), 0.125)
    expect_equal("/sample doubles", list(attrs.get("doubles", [])), [0.5, 1.5])
    expect_equal("/sample doubles dtype", attrs["doubles"].dtype, np.dtype("float64"))
    expect_equal("/sample ints", list(attrs.get("ints", [])), [1, -2, 3])
    expect_equal("/sample ints dtype", attrs["ints"].dtype, np.dtype("int64"))


def check_spherical(f):
    expect("spherical/sample" in f, "group /spherical/sample is missing")
    g = f["spherical/sample"]
    expect_equal("/spherical/sample method", g.attrs.get("method"), "sphere")
    expect_equal("/spherical/sample domain", g.attrs.get("domain"), "octa")
    expect_equal("/spherical/sample n", g.attrs.get("n"), 2)
    expect_equal("/spherical/sample source", g.attrs.get("source"), "octahedron.ply")
    expect_equal("/spherical/sample psnr", g.attrs.get("psnr"), 80.5)
    geometry = g["geometry"]
    expect_equal("geometry dtype", geometry.dtype, np.dtype("float32"))
    expect_equal("geometry shape", geometry.shape, (5, 5, 3))
    for key, want in (("domain", "octa"), ("n", 2), ("faces", 1), ("width", 5), ("height", 5)):
        expect_equal(f"geometry {key}", geometry.attrs.get(key), want)
    xyz = geometry[()]
    mask = g["mask"][()]
    expect_equal("mask dtype", g["mask"].dtype, np.dtype("uint8"))
    expect_equal("mask shape", mask.shape, (5, 5))
    want_mask = np.ones((5, 5), dtype=np.uint8)
    want_mask[2, 2] = 0
    expect(np.array_equal(mask, want_mask), f"mask: got {mask.tolist()}")
    expect(bool(np.isnan(xyz[mask == 0]).all()), "undefined samples are not NaN")
    want = (np.arange(75, dtype=np.float32) * 0.25).reshape(5, 5, 3)
    expect(np.array_equal(xyz[mask == 1], want[mask == 1]), "defined samples differ")
    sphere = g["parametrization/sphere"]
    expect_equal("sphere dtype", sphere.dtype, np.dtype("float64"))
    expect_equal("sphere shape", sphere.shape, (7, 3))
    expect_equal("sphere input_vertices", sphere.attrs.get("input_vertices"), 6)
    expect_equal("sphere input_faces", sphere.attrs.get("input_faces"), 8)
    expect(np.allclose(np.linalg.norm(sphere[()], axis=1), 1.0), "sphere rows are not unit vectors")


def main():
    if len(sys.argv) != 3:
        print("usage: check_archive.py WRITER OUT.h5", file=sys.stderr)
        return 2
    writer, out = sys.argv[1], sys.argv[2]
    run_writer(writer, out)
    with h5py.File(out, "r") as f:
        check_root(f)
        check_sample(f)
        check_spherical(f)
    print("h5py check passed")
    return 0


try:
    import h5py
    import numpy as np
except ImportError as error:
    fail(f"h5py and numpy are needed (Debian: python3-h5py): {error}")

if __name__ == "__main__":
    sys.exit(main())
