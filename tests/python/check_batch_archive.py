#!/usr/bin/env python3
"""Checks a batch archive with h5py and with examples/load_archive.py.

Usage: check_batch_archive.py WRITER OUT.h5 LOADER

Runs WRITER (the write_batch_archive executable) to produce OUT.h5, checks with h5py every dataset, shape,
dtype, chunk shape, filter and attribute that write_batch_archive.cpp documents (docs/archive.md, "Batch
archives"), then loads it through LOADER (examples/load_archive.py): its GimforgeDataset class and its
command line. Then damages copies of it with h5py as a hostile archive would (wrong types and shapes, declared
extents the file does not hold, indices out of range, soft and external links) and checks that the loader
refuses each with one error line naming the item and the cause. Exits 1 naming the first mismatch; prints
"batch archive check passed" when all match.
"""
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile

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


def load_module(loader_path):
    spec = importlib.util.spec_from_file_location("load_archive", loader_path)
    loader = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loader)
    return loader


def check_loader(loader, loader_path, out):
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


def replace(group, name, data, **kwargs):
    """Replaces dataset group[name] by one holding `data`."""
    del group[name]
    group.create_dataset(name, data=data, **kwargs)


def relink(group, name, link):
    del group[name]
    group[name] = link


def add_mcgim_output(f):
    """A one-item multi-chart output /batch/mcgim_t (a 3 x 2 image of one chart), laid out as batch writes it."""
    g = f.create_group("batch/mcgim_t")
    g.attrs.update({"count": 1, "failed_count": 0, "method": "mcgim"})
    for key, value in (("names", "chair/a"), ("sources", "meshes/chair/a.ply"), ("labels", "chair"),
                       ("label_names", "chair")):
        g.create_dataset(key, data=np.array([value], dtype=h5py.string_dtype()))
    g["index"], g["label_index"], g["metrics/psnr"] = np.zeros(1, "i8"), np.zeros(1, "i4"), np.array([70.0])
    for key in ("names", "sources", "labels", "reasons"):
        g.create_dataset(f"failed/{key}", shape=(0,), dtype=h5py.string_dtype())
    g["failed/index"], g["failed/attempts"] = np.zeros(0, "i8"), np.zeros(0, "i4")
    item = g.create_group("items/0")
    item.attrs.update({"method": "mcgim", "source": "meshes/chair/a.ply", "width": 2, "height": 3, "num_charts": 1})
    item["geometry"] = np.arange(18, dtype="f4").reshape(3, 2, 3)
    item["mask"], item["chart"] = np.ones((3, 2), "u1"), np.zeros((3, 2), "i4")
    item["zipper"], item["chart_stretch"] = np.zeros((0, 2), "i4"), np.ones(1)


def check_hostile(loader, loader_path, out):
    """Damaged copies of `out` (with the multi-chart output of add_mcgim_output): the loader refuses each
    with ArchiveError naming the item and the cause, and its command line with one line and exit code 1."""
    gim, mcgim = "batch/gim_9", "batch/mcgim_t/items/0"
    cases = {  # name: (edit, output, the item the error names, what its cause says)
        "label_index": (lambda f: replace(f[gim], "label_index", np.array([5, 0, 0], "i4")), "gim_9", gim,
                        "dataset 'label_index' holds 5 at 0, outside [-1, 1]"),
        "names_int": (lambda f: replace(f[gim], "names", np.arange(3)), "gim_9", gim,
                      "dataset 'names' holds int64, expected strings"),
        "metrics_str": (lambda f: replace(f[gim + "/metrics"], "psnr", np.array(["a", "b", "c"], h5py.string_dtype())),
                        "gim_9", gim + "/metrics", "dataset 'psnr' holds strings, expected float64"),
        "scalar_data": (lambda f: replace(f[gim], "data", np.float32(1)), "gim_9", gim,
                        "dataset 'data' has shape (), expected (3, 3, 9, 9)"),
        # 447 GiB declared, nothing stored: refused before anything is allocated
        "declared_data": (lambda f: replace(f[gim], "data", None, shape=(3, 3, 200000, 200000), dtype="f4",
                                            chunks=(1, 1, 64, 64)), "gim_9", gim, "expected (3, 3, 9, 9)"),
        "unwritten_data": (lambda f: replace(f[gim], "data", None, shape=(3, 3, 9, 9), dtype="f4", chunks=(1, 3, 9, 9)),
                           "gim_9", gim, "dataset 'data' stores 0 of its 3 chunks"),
        "nan_sample": (lambda f: f[gim + "/data"].__setitem__((0, 1, 2, 3), np.nan), "gim_9", gim,
                       "dataset 'data' of item 0 ('chair/a') holds nan at (1, 2, 3), which is not finite"),
        # Finite, but where no mesh lies: gimforge refuses such a sample too (io/coded_image.h, far_sample_problem).
        "far_sample": (lambda f: f[gim + "/data"].__setitem__((0, 1, 2, 3), 3e38), "gim_9", gim,
                       "dataset 'data' of item 0 ('chair/a') holds 3.0000000054977558e+38 at (1, 2, 3), outside [-1e+18, 1e+18]"),
        "soft_self": (lambda f: relink(f[gim], "data", h5py.SoftLink(f"/{gim}/data")), "gim_9", gim + "/data",
                      "is a soft link"),
        "external": (lambda f: relink(f[gim], "data", h5py.ExternalLink(out, f"/{gim}/data")), "gim_9", gim + "/data",
                     "is an external link"),
        "batch_dataset": (lambda f: relink(f, "batch", np.arange(2)), None, "batch", "is not a group"),
        "sphere_mask": (lambda f: replace(f["batch/sphere_octa_2"], "mask", np.ones((2, 1, 5, 4), "u1")),
                        "sphere_octa_2", "batch/sphere_octa_2",
                        "dataset 'mask' has shape (2, 1, 5, 4), expected (2, 1, 5, 5)"),
        "mcgim_mask": (lambda f: replace(f[mcgim], "mask", np.ones((1, 2), "u1")), "mcgim_t", mcgim,
                       "dataset 'mask' has shape (1, 2), expected (3, 2)"),
        "mcgim_chart": (lambda f: f[mcgim + "/chart"].__setitem__((0, 0), 4), "mcgim_t", mcgim,
                        "dataset 'chart' holds 4 at (0, 0), outside [-1, 0]"),
        "mcgim_width": (lambda f: f[mcgim].attrs.__setitem__("width", 2 ** 40), "mcgim_t", mcgim,
                        "attribute width = 1099511627776, outside [1, 67108864]"),
        # Once read as input coordinates with the origin zero (an archive older than the local frame).
        "partial_origin": (lambda f: f["batch/sphere_octa_2/metrics"].__delitem__("frame_origin_y"), "sphere_octa_2",
                           "batch/sphere_octa_2/metrics", "the metrics hold only some of frame_origin_x"),
        "dotdot_name": (lambda f: replace(f[gim], "names", ["a/../b", "b", "c"], dtype=h5py.string_dtype()),
                        "gim_9", gim, "dataset 'names' holds 'a/../b', not 3 distinct relative paths"),
        "twice_name": (lambda f: replace(f[gim], "names", ["a", "a", "c"], dtype=h5py.string_dtype()), "gim_9", gim,
                       "dataset 'names' holds a name twice"),
    }
    with tempfile.TemporaryDirectory() as tmp:
        valid = os.path.join(tmp, "valid.h5")
        shutil.copy(out, valid)
        with h5py.File(valid, "r+") as f:
            add_mcgim_output(f)
        item = loader.GimforgeDataset(valid, "mcgim_t", frame="local")[0]
        expect(np.array_equal(item["mcgim"]["geometry"], np.arange(18, dtype="f4").reshape(3, 2, 3)),
               "the multi-chart item of add_mcgim_output does not load")
        # A name with control characters loads (gimforge's readers take it) and is printed escaped: once a
        # crafted name cleared the screen and forged lines.
        forged = os.path.join(tmp, "forged.h5")
        shutil.copy(valid, forged)
        with h5py.File(forged, "r+") as f:
            replace(f[gim], "names", ["x\n\x1b[2J", "b", "c"], dtype=h5py.string_dtype())
        result = subprocess.run([sys.executable, loader_path, forged], capture_output=True, text=True, check=False)
        expect(result.returncode == 0 and "\x1b" not in result.stdout and "first item: x\\n\\x1b[2J" in result.stdout,
               f"forged name: exit {result.returncode}, stdout {result.stdout!r}")
        for name, (edit, output, where, cause) in cases.items():
            path = os.path.join(tmp, f"{name}.h5")
            shutil.copy(valid, path)
            with h5py.File(path, "r+") as f:
                edit(f)
            want = f"{path}:/{where}: "
            try:
                loader.GimforgeDataset(path, output)[0]
                fail(f"{name}: the loader accepted the damaged archive")
            except loader.ArchiveError as e:
                expect(str(e).startswith(want) and cause in e.cause,
                       f"{name}: ArchiveError {e}, expected {want}...{cause}")
            result = subprocess.run([sys.executable, loader_path, path], capture_output=True, text=True, check=False)
            expect(result.returncode == 1 and result.stderr.count("\n") == 1, f"{name}: exit code {result.returncode}, "
                                                                              f"stderr {result.stderr!r}")
            expect(result.stderr.startswith(f"load_archive.py: error: {want}") and cause in result.stderr,
                   f"{name}: error line {result.stderr!r}, expected {want}...{cause}")


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
    loader = load_module(loader_path)
    check_loader(loader, loader_path, out)
    check_hostile(loader, loader_path, out)
    print("batch archive check passed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
