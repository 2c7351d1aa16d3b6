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
    expect_equal("/ format_version", version, 1)
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


def main():
    if len(sys.argv) != 3:
        print("usage: check_archive.py WRITER OUT.h5", file=sys.stderr)
        return 2
    writer, out = sys.argv[1], sys.argv[2]
    run_writer(writer, out)
    with h5py.File(out, "r") as f:
        check_root(f)
        check_sample(f)
    print("h5py check passed")
    return 0


try:
    import h5py
    import numpy as np
except ImportError as error:
    fail(f"h5py and numpy are needed (Debian: python3-h5py): {error}")

if __name__ == "__main__":
    sys.exit(main())
