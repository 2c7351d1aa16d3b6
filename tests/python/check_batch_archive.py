#!/usr/bin/env python3
"""Checks a batch archive with h5py and with examples/load_archive.py.

Usage: check_batch_archive.py WRITER OUT.h5 LOADER

Runs WRITER (the write_batch_archive executable) to produce OUT.h5, checks with h5py every dataset, shape,
dtype, chunk shape, filter and attribute that write_batch_archive.cpp documents (docs/archive.md, "Batch
archives"), then loads it through LOADER (examples/load_archive.py): its GimforgeDataset class and its
command line. Exits 1 naming the first mismatch; prints "batch archive check passed" when all match.
"""
import importlib.util
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_archive import expect, expect_equal, fail, h5py, np, run_writer  # noqa: E402 (the shared checks)


def strings(ds):
    return [str(s) for s in ds.asstr()[()]]


def item_values(side, scale, offset):
    return (offset + scale * np.arange(3 * side * side, dtype=np.float64)).astype(np.float32).reshape(3, side, side)


def check_stack(ds, shape, chunks):
    expect_equal(f"{ds.name} dtype", ds.dtype, np.dtype("float32") if ds.name.endswith("data") else np.dtype("uint8"))
    expect_equal(f"{ds.name} shape", ds.shape, shape)
    expect_equal(f"{ds.name} chunks", ds.chunks, chunks)
    expect_equal(f"{ds.name} compression", ds.compression, "gzip")
    expect_equal(f"{ds.name} shuffle", ds.shuffle, True)


def check_gim(f):
    g = f["batch/gim_9"]
    check_stack(g["data"], (3, 3, 9, 9), (1, 3, 9, 9))
    data = g["data"][()]
    for index in range(3):
        want = item_values(9, 0.5, 1000.0 * index)
        expect(np.array_equal(data[index], want), f"gim_9 data[{index}] differs from item {index}")
    expect("mask" not in g, "gim_9 has a mask although no item has one")
    expect_equal("gim_9 names", strings(g["names"]), ["chair/a", "table/b", "chair/c"])
    expect_equal("gim_9 sources", strings(g["sources"])[1], "meshes/table/b.ply")
    expect_equal("gim_9 labels", strings(g["labels"]), ["chair", "table", "chair"])
    expect_equal("gim_9 index", g["index"][()].tolist(), [0, 1, 2])
    expect_equal("gim_9 index dtype", g["index"].dtype, np.dtype("int64"))
    expect_equal("gim_9 label_names", strings(g["label_names"]), ["chair", "table"])
    expect_equal("gim_9 label_index", g["label_index"][()].tolist(), [0, 1, 0])
    expect_equal("gim_9 label_index dtype", g["label_index"].dtype, np.dtype("int32"))
    expect(h5py.check_string_dtype(g["names"].dtype).length is None, "names are not variable-length")
    expect_equal("names encoding", h5py.check_string_dtype(g["names"].dtype).encoding, "utf-8")
    expect_equal("gim_9 metrics", sorted(g["metrics"].keys()), ["hausdorff_rms", "psnr"])
    expect_equal("gim_9 psnr", g["metrics/psnr"][()].tolist(), [60.0, 61.0, 62.0])
    rms = g["metrics/hausdorff_rms"][()]
    expect_equal("hausdorff_rms dtype", rms.dtype, np.dtype("float64"))
    expect(np.isnan(rms[0]) and rms[1] == 0.125 and np.isnan(rms[2]), f"gim_9 hausdorff_rms {rms!r}")
    failed = g["failed"]
    expect_equal("gim_9 failed names", strings(failed["names"]), ["table/d"])
    expect_equal("gim_9 failed reasons", strings(failed["reasons"]), ["bad mesh: not manifold"])
    expect_equal("gim_9 failed attempts", failed["attempts"][()].tolist(), [2])
    expect_equal("gim_9 failed index", failed["index"][()].tolist(), [3])
    expect_equal("gim_9 attributes", {k: g.attrs[k] for k in ("method", "size", "count", "failed_count")},
                 {"method": "gim", "size": "9", "count": 3, "failed_count": 1})


def check_sphere(f):
    g = f["batch/sphere_octa_2"]
    check_stack(g["data"], (2, 3, 5, 5), (1, 3, 5, 5))
    for index in range(2):
        expect(np.array_equal(g["data"][index], item_values(5, -0.25, -index)), f"sphere data[{index}] differs")
    check_stack(g["mask"], (2, 1, 5, 5), (1, 1, 5, 5))
    mask = g["mask"][()]
    expect(mask[0, 0, 2, 2] == 0 and mask[0].sum() == 24, f"sphere mask of item 0: {mask[0]!r}")
    expect(bool((mask[1] == 1).all()), "item without a mask is not stored as all ones")
    expect_equal("sphere label_index", g["label_index"][()].tolist(), [0, -1])
    expect_equal("sphere label_names", strings(g["label_names"]), ["chair"])
    expect_equal("sphere failed", len(g["failed/names"]), 0)
    expect_equal("sphere attributes", {k: g.attrs[k] for k in ("method", "domain", "n")},
                 {"method": "sphere", "domain": "octa", "n": "2"})


def check_loader(loader_path, out):
    spec = importlib.util.spec_from_file_location("load_archive", loader_path)
    loader = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loader)

    ds = loader.GimforgeDataset(out, "gim_9")
    expect_equal("GimforgeDataset length", len(ds), 3)
    item = ds[1]
    expect_equal("GimforgeDataset item name", item["name"], "table/b")
    expect_equal("GimforgeDataset item label", item["label"], 1)
    expect(np.array_equal(np.asarray(item["data"]), item_values(9, 0.5, 1000.0)), "GimforgeDataset data of item 1")
    expect_equal("GimforgeDataset negative index", ds[-1]["name"], "chair/c")
    try:
        ds[3]
        fail("GimforgeDataset[3] did not raise IndexError")
    except IndexError:
        pass
    expect_equal("GimforgeDataset origin without frame_origin metrics", np.asarray(item["origin"]).tolist(),
                 [0.0, 0.0, 0.0])
    expect_equal("GimforgeDataset data dtype without frame_origin metrics", np.asarray(item["data"]).dtype,
                 np.dtype("float32"))
    masked = loader.GimforgeDataset(out, "sphere_octa_2")
    expect_equal("GimforgeDataset mask shape", tuple(np.asarray(masked[0]["mask"]).shape), (1, 5, 5))
    # Positions come back in the input's coordinates (frame origin added, float64) unless frame="local".
    origins = [np.array([4e5, 5e6, 250.5]), np.array([-1e7, 0.125, 0.0])]
    local = loader.GimforgeDataset(out, "sphere_octa_2", frame="local")
    for index in range(2):
        stored = item_values(5, -0.25, -index)
        world = np.asarray(masked[index]["data"])
        expect_equal(f"sphere item {index} origin", np.asarray(masked[index]["origin"]).tolist(),
                     origins[index].tolist())
        expect_equal(f"sphere item {index} data dtype", world.dtype, np.dtype("float64"))
        expect(np.array_equal(world, stored.astype(np.float64) + origins[index][:, None, None]),
               f"sphere item {index}: the frame origin is not added back")
        expect(np.array_equal(np.asarray(local[index]["data"]), stored), f"sphere item {index}: frame='local' changed")
    try:
        loader.GimforgeDataset(out, "sphere_octa_2", frame="world")
        fail("GimforgeDataset accepted frame='world'")
    except ValueError:
        pass
    try:
        loader.GimforgeDataset(out)
        fail("GimforgeDataset without an output did not refuse an archive with two outputs")
    except ValueError:
        pass

    summary = loader.batch_outputs(out)
    expect_equal("batch_outputs keys", list(summary), ["gim_9", "sphere_octa_2"])
    expect_equal("batch_outputs gim_9 shape", summary["gim_9"]["item_shape"], (3, 9, 9))
    expect_equal("batch_outputs gim_9 failed", summary["gim_9"]["failed"],
                 [{"name": "table/d", "source": "meshes/table/d.ply", "reason": "bad mesh: not manifold",
                   "attempts": 2}])

    result = subprocess.run([sys.executable, loader_path, out], capture_output=True, text=True, check=False)
    expect(result.returncode == 0, f"load_archive.py exited with {result.returncode}: {result.stderr.strip()}")
    for needle in ("[gim_9]", "items: 3  shape (C, H, W): 3x9x9  mask: no", "chair: 2, table: 1",
                   "table/d (meshes/table/d.ply), 2 attempt(s): bad mesh: not manifold",
                   "first item metrics: psnr=60", "[sphere_octa_2]", "mask: yes", "(none): 1"):
        expect(needle in result.stdout, f"load_archive.py output lacks {needle!r}:\n{result.stdout}")


def main(argv):
    if len(argv) != 4:
        print("usage: check_batch_archive.py WRITER OUT.h5 LOADER", file=sys.stderr)
        return 2
    writer, out, loader_path = argv[1:]
    run_writer(writer, out)
    with h5py.File(out, "r") as f:
        expect_equal("/ format", f.attrs.get("format"), "gimforge")
        expect_equal("/batch outputs", sorted(f["batch"].keys()), ["gim_9", "sphere_octa_2"])
        check_gim(f)
        check_sphere(f)
    check_loader(loader_path, out)
    print("batch archive check passed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
