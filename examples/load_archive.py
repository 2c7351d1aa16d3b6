#!/usr/bin/env python3
"""Read a gimforge batch archive with h5py, and feed it to PyTorch.

A batch archive (`gimforge batch ... -o ARCHIVE.h5`; layout in docs/archive.md, "Batch archives") holds
one group per output, /batch/<output>, with the items stacked as `data` (N, C, H, W) float32, one item per
HDF5 chunk (geometry images, spherical geometry images), or, for relief maps and multi-chart geometry images,
whose size differs from item to item, one group per item `items/<k>` with the layout of a converted relief map
(/relief/<name>) or multi-chart image (/mcgim/<name>), and for `batch --codec` a compressed image group
(docs/compression.md: quantized ones are read here, coded ones after `gimforge decompress`); plus names,
labels, per-item metrics and a table of the items that failed.

Positions are stored in each item's local frame (docs/archive.md, "Local frame and origin"): relative to
the centre of the input mesh's bounding box, its `frame_origin` (float64, metrics frame_origin_x/y/z of the
output, or the attribute of a relief item's group). The loader adds it back by default (frame="input"): the
positions it returns are the input mesh's coordinates, as float64 since float32 cannot hold georeferenced
ones (UTM northings of 5e6 to a millimetre); frame="local" returns the stored float32 positions unchanged
(what a network should see) with the origin beside them. Archives written before the local frame have no
origin: it reads as zero and nothing changes.

Usage:
    python3 examples/load_archive.py ARCHIVE.h5      # prints outputs, counts, shapes, labels, failures

In Python:
    from load_archive import GimforgeDataset
    ds = GimforgeDataset("ARCHIVE.h5", "gim_257")
    item = ds[0]            # {"data": (C, H, W), "origin": (3,) float64, "label": int, "name": str, ...}
    local = GimforgeDataset("ARCHIVE.h5", "gim_257", frame="local")   # float32, relative to item["origin"]
    rows, units = ds.sideband(0)   # geometry images: item 0's sideband (q, 3) int32, the cut's gluing
    relief = GimforgeDataset("ARCHIVE.h5", "relief_auto_64")
    item = relief[0]        # {"relief": {"distances": (L, T, T) uint16, "cells": (G, 3), ...}, "attrs": {...}, ...}
    # with PyTorch installed, GimforgeDataset is a torch.utils.data.Dataset returning tensors:
    # loader = torch.utils.data.DataLoader(ds, batch_size=32, shuffle=True, num_workers=4)

Single images of `convert` and `compress` archives (/gim/<name>, /spherical/<name>), float32 or quantized:
    from load_archive import read_image
    img = read_image("out.h5", "gim/bunny")      # {"positions": (H, W, 3) float64, "mask": ..., "storage": ...}

Needs h5py and numpy (Debian: python3-h5py). PyTorch is used only when it is installed.
"""
import sys

import h5py
import numpy as np

try:  # optional: without PyTorch the dataset is a plain class returning numpy arrays
    import torch
    from torch.utils.data import Dataset as _DatasetBase
except ImportError:
    torch = None
    _DatasetBase = object

BATCH_GROUP = "batch"
ORIGIN_METRICS = ("frame_origin_x", "frame_origin_y", "frame_origin_z")
FRAMES = ("input", "local")


def frame_origin(group):
    """The `frame_origin` attribute of a representation group (/gim/<name>, /spherical/<name>,
    /relief/<name> or a batch's items/<k>) as a float64 array (3,): what to add to its positions to get the
    input mesh's coordinates; zeros when absent (an archive written before the local frame)."""
    if "frame_origin" not in group.attrs:
        return np.zeros(3)
    origin = np.asarray(group.attrs["frame_origin"], dtype=np.float64)
    if origin.shape != (3,) or not (np.abs(origin) <= 1e12).all():
        raise ValueError(f"{group.file.filename}:{group.name}: attribute frame_origin is not 3 finite numbers "
                         "within ±1e12")
    return origin


def read_image(path, item, frame="input"):
    """One geometry image, spherical or multi-chart geometry image of an archive (`item` = "gim/NAME",
    "spherical/NAME" or "mcgim/NAME")
    as a dict {"positions": (H, W, 3), "mask": (H, W) bool or None, "storage": str}. Positions are float64 in the
    input's coordinates (frame="input") or the stored local frame (frame="local"); NaN where the mask is 0.
    Reads what `convert` writes (float32) and what `gimforge compress --codec quant12|quant16` writes (uint16
    with per-axis `scale` and `offset`: offset + scale * q). Items coded with j2k or wavelet
    (`geometry_code`, docs/archive.md "Compressed items") need gimforge's decoders and, for geometry images,
    the fusing of the cut from the sideband: decode them with `gimforge decompress ARCHIVE -o OUT.h5` and read
    OUT.h5."""
    if frame not in FRAMES:
        raise ValueError(f"frame must be one of {FRAMES}, not {frame!r}")
    with h5py.File(path, "r") as f:
        if item not in f or not isinstance(f[item], h5py.Group):
            raise KeyError(f"{path}: no item '{item}'")
        if item.startswith("relief/") or _method(f[item]) == "relief":
            raise ValueError(f"{path}: '{item}' is a relief map, not an image of positions: read it with "
                             "GimforgeDataset, or as docs/archive.md (\"Relief maps\") describes")
        return _read_positions(path, f[item], frame)


def _read_positions(path, g, frame):
    """read_image() of an open group (/gim/<name>, /spherical/<name>, /mcgim/<name>, or a batch item items/<k>)."""
    if "geometry_code" in g:
        codec = _strings_attr(g["geometry_code"].attrs.get("codec", "?"))
        raise ValueError(f"{path}:{g.name} is coded with '{codec}': decode it with `gimforge decompress {path} -o OUT.h5` "
                         "and read OUT.h5")
    ds = g["geometry"]
    q = ds[()]
    if q.dtype == np.float32:
        positions, storage = q.astype(np.float64), "float32"
    elif q.dtype == np.uint16:
        positions, bits = _dequantize(path, g.name + "/geometry", ds, q)
        storage = f"quant{bits}"
    else:
        raise ValueError(f"{path}:{g.name}/geometry has type {q.dtype} (float32 or quantized uint16)")
    mask = g["mask"][()] == 1 if "mask" in g else None
    if mask is not None:
        positions[~mask] = np.nan
    if frame == "input":
        positions = positions + frame_origin(g)
    return {"positions": positions, "mask": mask, "storage": storage}


def _dequantize(path, name, ds, q):
    """offset + scale * q of a quantized (H, W, 3) dataset, with the checks gimforge's readers make
    (io/coded_image.cpp): `bits` an integer 8, 12 or 16 (absent: 16), every q < 2^bits, `scale` and `offset`
    float64 (1 or 3 values), scale > 0 and offset + scale * (2^bits - 1) within float32. Returns (positions,
    bits)."""
    def bad(what):
        return ValueError(f"{path}:{name}: {what}")
    bits = ds.attrs.get("bits", 16)
    if not isinstance(bits, (int, np.integer)) or isinstance(bits, (bool, np.bool_)) or int(bits) not in (8, 12, 16):
        raise bad(f"bits = {bits!r} (expected the integer 8, 12 or 16)")
    bits = int(bits)
    top = 2.0 ** bits - 1.0
    if q.size and int(q.max()) > top:
        raise bad(f"value {int(q.max())} is above 2^bits - 1 = {int(top)}")
    if "scale" not in ds.attrs or "offset" not in ds.attrs:
        raise bad("quantized without 'scale' and 'offset'")
    values = []
    for key in ("scale", "offset"):
        v = np.asarray(ds.attrs[key])
        if v.dtype != np.float64 or v.size not in (1, 3):
            raise bad(f"'{key}' is not 1 or 3 float64 values")
        values.append(np.broadcast_to(v.reshape(-1), (3,)).astype(np.float64))
    scale, offset = values
    limit = float(np.finfo(np.float32).max)
    if not (np.isfinite(scale).all() and (scale > 0).all() and (np.abs(offset) + scale * top < limit).all()):
        raise bad(f"scale {scale.tolist()} and offset {offset.tolist()} leave the range of float32 values")
    return offset + scale * q.astype(np.float64), bits


def _origins(path, output, g):
    """The (N, 3) float64 frame origins of an output's items (metrics frame_origin_x/y/z), or None when the
    archive predates them."""
    metrics = g["metrics"]
    if not all(k in metrics for k in ORIGIN_METRICS):
        return None
    origins = np.stack([metrics[k][()] for k in ORIGIN_METRICS], axis=1).astype(np.float64)
    if not np.isfinite(origins).all():
        raise ValueError(f"{path}: output '{output}': metrics frame_origin_* are not finite for every item")
    return origins


def _strings_attr(value):
    return value.decode() if isinstance(value, bytes) else value


def _check_sample_uv(path, output, g, item_shape, count):
    """Refuses a batch output's `sample_uv` that is not a float32 (N, 2, H, W) dataset beside `data`."""
    ds = g["sample_uv"]
    if not isinstance(ds, h5py.Dataset):
        raise ValueError(f"{path}: output '{output}': 'sample_uv' is not a dataset")
    if ds.dtype != np.float32:
        raise ValueError(f"{path}: output '{output}': dataset 'sample_uv' is {ds.dtype}, not float32")
    want = (count, 2) + (tuple(item_shape[1:]) if item_shape else ())
    if item_shape is None or ds.shape != want:
        raise ValueError(f"{path}: output '{output}': dataset 'sample_uv' has shape {ds.shape}, expected {want}")


def _strings(dataset):
    """A variable-length UTF-8 string dataset as a list of str."""
    return [str(s) for s in dataset.asstr()[()]]


def _method(group):
    """The `method` attribute of an item's group, as a str."""
    m = group.attrs.get("method", "")
    return m.decode() if isinstance(m, bytes) else str(m)


def _check_items(path, output, g):
    """A relief output's items group must hold exactly the groups 0..N-1 (N = the count attribute)."""
    count = int(g.attrs["count"])
    if "items" not in g:
        return
    items = g["items"]
    expected = {str(k) for k in range(count)}
    if set(items.keys()) != expected or not all(isinstance(items[k], h5py.Group) for k in expected):
        raise ValueError(f"{path}: output '{output}': group 'items' must hold exactly the groups 0..{count - 1} "
                         f"(it holds {len(items)} entries)")
    if len(g["names"]) != count:
        raise ValueError(f"{path}: output '{output}': {len(g['names'])} names for count {count}")


def batch_outputs(path):
    """The outputs of the batch archive at `path`: {output: summary dict}, sorted by name.

    Each summary holds: count (N), layout ("stacked" images, or "groups": relief maps,
    multi-chart images and compressed outputs, one group per item), item_shape
    ((C, H, W), or None when N is 0 or the items are groups), has_mask, names,
    label_names, label_counts ({label: items}, "" for unlabelled), metric_keys, failed (a list of
    {"name", "source", "reason", "attempts"}) and attributes (the group's attributes: method, size, ...).
    """
    with h5py.File(path, "r") as f:
        if BATCH_GROUP not in f:
            raise ValueError(f"{path}: not a batch archive (no /{BATCH_GROUP} group); a convert archive's images load "
                             "with read_image(path, 'gim/NAME')")
        summaries = {}
        for output, g in sorted(f[BATCH_GROUP].items()):
            _check_items(path, output, g)
            label_names = _strings(g["label_names"])
            label_index = g["label_index"][()]
            counts = {}
            for k in label_index:
                label = label_names[k] if k >= 0 else ""
                counts[label] = counts.get(label, 0) + 1
            failed = g["failed"]
            summaries[output] = {
                "count": int(g.attrs["count"]),
                "layout": "groups" if "items" in g else "stacked",
                "item_shape": tuple(g["data"].shape[1:]) if "data" in g and g["data"].shape[0] > 0 else None,
                "has_mask": "mask" in g,
                "has_sample_uv": "sample_uv" in g,
                "names": _strings(g["names"]),
                "label_names": label_names,
                "label_counts": counts,
                "metric_keys": sorted(g["metrics"].keys()),
                "failed": [
                    {"name": n, "source": s, "reason": r, "attempts": int(a)}
                    for n, s, r, a in zip(_strings(failed["names"]), _strings(failed["sources"]),
                                          _strings(failed["reasons"]), failed["attempts"][()])
                ],
                "attributes": {k: (v.decode() if isinstance(v, bytes) else v) for k, v in g.attrs.items()},
            }
        return summaries


class GimforgeDataset(_DatasetBase):
    """The items of one output of a gimforge batch archive, in archive (index) order.

    `ds[i]` is a dict:
      "data"    (C, H, W) — the geometry image (channels x, y, z, ...): with frame="input" (the default)
                in the input mesh's coordinates, float64 when the output records origins (float32 cannot hold
                georeferenced coordinates), float32 for archives without; with frame="local" the stored
                float32 values, relative to "origin"
      "origin"  (3,) float64 — the item's frame origin (zeros for archives written before it)
      "mask"    (1, H, W) uint8, 1 = defined sample (only when the output has a mask)
      "sample_uv" (2, H, W) float32 — where each sample lies in the parameter square (only for an output
                converted with --sampling adaptive; the uniform grid is (i/(W-1), j/(H-1)))
      "relief"  instead of data and mask, for a relief-map output: {dataset name: numpy array} of the item's
                group (cells, external_faces, case, projection, domain_faces, projection_params, layer_cell,
                layer_face, distances (L, T, T) uint16, normals (L, T, T, 3) int8, colors, grid_levels), with
                "attrs" the group's attributes (n, texture, origin, cell_size, psnr, ...) and
                "distance_scale" the world units of one distance step; docs/archive.md describes them.
                With frame="input" attrs["origin"] (the grid's corner) has the frame origin added, so the
                points computed from it are the input's coordinates; frame="local" leaves it as stored
      "mcgim"   instead of data and mask, for a multi-chart geometry-image output: {dataset name: numpy
                array} of the item's group: geometry (H, W, 3) (NaN where undefined; float64 in the input's
                coordinates with frame="input"), mask (H, W) uint8, chart (H, W) int32, zipper (q, 2) int32
                (sample, representative), normals, chart_stretch; "attrs" the group's attributes (width,
                height, psnr, packing_efficiency, ...). Items differ in W and H
      "label"   int, position in `ds.label_names`, -1 for an unlabelled item
      "name"    str, the item name;  "index": int, its position in the sorted collection
    With PyTorch installed the arrays are torch tensors and the class is a torch.utils.data.Dataset,
    so a DataLoader batches it directly. `transform`, if given, is applied to each dict.

    The file is opened lazily in each process (and not pickled), so DataLoader workers each get their
    own h5py handle. Reading one item reads exactly one HDF5 chunk per dataset.
    """

    def __init__(self, path, output=None, transform=None, frame="input"):
        if frame not in FRAMES:
            raise ValueError(f"frame must be one of {', '.join(FRAMES)}, not {frame!r}")
        self.path = str(path)
        self.transform = transform
        self.frame = frame
        self._file = None
        with h5py.File(self.path, "r") as f:
            if BATCH_GROUP not in f:
                raise ValueError(f"{self.path}: not a batch archive (no /{BATCH_GROUP} group); a convert archive's "
                                 "images load with read_image(path, 'gim/NAME')")
            outputs = sorted(f[BATCH_GROUP].keys())
            if output is None:
                if len(outputs) != 1:
                    raise ValueError(f"{self.path}: choose an output: {', '.join(outputs)}")
                output = outputs[0]
            if output not in outputs:
                raise KeyError(f"{self.path}: no output '{output}' (has: {', '.join(outputs)})")
            g = f[BATCH_GROUP][output]
            _check_items(self.path, output, g)
            self.output = output
            self.names = _strings(g["names"])
            self.sources = _strings(g["sources"])
            self.indices = g["index"][()]
            self.labels = g["label_index"][()]
            self.label_names = _strings(g["label_names"])
            self.has_mask = "mask" in g
            self.has_sample_uv = "sample_uv" in g
            self.groups = "items" in g
            self.item_shape = None if self.groups else tuple(g["data"].shape[1:])
            self.metrics = {k: v[()] for k, v in g["metrics"].items()}
            self.attributes = dict(g.attrs)
            self.origins = _origins(self.path, output, g)  # (N, 3) float64, or None (older archives)
            if self.has_sample_uv:
                _check_sample_uv(self.path, output, g, self.item_shape, len(self.names))
            elif _strings_attr(g.attrs.get("sampling")) == "adaptive" and not self.groups:
                raise ValueError(f"{self.path}: output '{output}' was converted with adaptive sampling but has no "
                                 "dataset 'sample_uv'")

    def origin(self, i):
        """The frame origin of item i, (3,) float64 (zeros when the archive has none)."""
        return np.zeros(3) if self.origins is None else self.origins[i].copy()

    def sideband(self, i):
        """Geometry-image outputs: item i's sideband, (q, 3) int32 rows label, start_unit, units (the cut's
        gluing, as /gim/<name>/sideband holds it; docs/archive.md), with `units_per_side`: from the output's
        stacked table, or from items/<k>/sideband in a compressed output (batch --codec); None when the output
        or the item has none (archives written before 2026-12-06). Not part of __getitem__: its length
        differs from item to item, which a DataLoader cannot stack. Raises IndexError for an index out of
        range and ValueError naming the file and output for damaged tables."""
        n = len(self)
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise TypeError(f"item index must be an integer, not {type(i).__name__}")
        asked, i = int(i), int(i) + (n if int(i) < 0 else 0)
        if not 0 <= i < n:
            raise IndexError(f"item {asked} out of range for {n} items")
        g = self._group()

        def bad(what):
            return ValueError(f"{self.path}: output '{self.output}': {what}")

        if "sideband" not in g and "sideband_offsets" not in g:
            item = g["items"].get(str(i)) if isinstance(g.get("items"), h5py.Group) else None
            if not isinstance(item, h5py.Group) or "sideband" not in item:
                return None
            table, units = item["sideband"], item.attrs.get("units_per_side")
            if not isinstance(table, h5py.Dataset) or table.dtype.kind != "i" or table.dtype.itemsize != 4 \
                    or table.ndim != 2 or table.shape[1] != 3:
                raise bad(f"item {i}'s 'sideband' is not an int32 (q, 3) table")
            if units is None or np.ndim(units) != 0 or not np.issubdtype(np.asarray(units).dtype, np.integer) or units < 1:
                raise bad(f"item {i} has no integer units_per_side >= 1")
            if table.shape[0] > 4 * int(units):
                raise bad(f"item {i}'s sideband has {table.shape[0]} rows, more than 4 * units_per_side")
            return table[()], int(units)

        table, offsets = g.get("sideband"), g.get("sideband_offsets")
        if not isinstance(table, h5py.Dataset) or not isinstance(offsets, h5py.Dataset):
            raise bad("'sideband' and 'sideband_offsets' must both be datasets")
        if table.dtype != np.int32 or table.ndim != 2 or table.shape[1] != 3:
            raise bad("'sideband' is not an int32 (S, 3) table")
        if offsets.dtype != np.int64 or offsets.shape != (n + 1,):
            raise bad(f"'sideband_offsets' is not int64 ({n + 1},)")
        o = offsets[()]
        if o[0] != 0 or o[-1] != table.shape[0] or np.any(np.diff(o) < 0):
            raise bad("'sideband_offsets' does not index 'sideband' (0 first, never decreasing, its rows last)")
        start, end = int(o[i]), int(o[i + 1])
        if start == end:
            return None
        units = table.attrs.get("units_per_side")
        if units is None or np.ndim(units) != 0 or not np.issubdtype(np.asarray(units).dtype, np.integer) or units < 1:
            raise bad("'sideband' has no integer units_per_side >= 1")
        if end - start > 4 * int(units):
            raise bad(f"item {i}'s sideband has {end - start} rows, more than 4 * units_per_side")
        return table[start:end], int(units)

    def __len__(self):
        return len(self.names)

    def _group(self):
        if self._file is None:
            self._file = h5py.File(self.path, "r")
        return self._file[BATCH_GROUP][self.output]

    def __getitem__(self, i):
        n = len(self)
        i = int(i)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"item {i} out of range for {n} items")
        g = self._group()
        item = {"label": int(self.labels[i]), "name": self.names[i], "index": int(self.indices[i])}
        if self.groups and _method(g["items"][str(i)]) in ("gim", "sphere"):
            # batch --codec: a quantized item is read here; a coded one needs `gimforge decompress`
            r = _read_positions(self.path, g["items"][str(i)], self.frame)
            data = np.ascontiguousarray(np.moveaxis(r["positions"], -1, 0))  # (3, H, W) like the stacked outputs
            item["data"] = data if self.frame == "input" else data.astype(np.float32)
            item["origin"] = frame_origin(g["items"][str(i)])
            if r["mask"] is not None:
                item["mask"] = r["mask"][None].astype(np.uint8)
            if torch is not None:
                item["data"] = torch.from_numpy(item["data"])
                item["origin"] = torch.from_numpy(item["origin"])
                if "mask" in item:
                    item["mask"] = torch.from_numpy(item["mask"])
            return self.transform(item) if self.transform is not None else item
        if self.groups and _method(g["items"][str(i)]) == "mcgim":
            group = g["items"][str(i)]
            item["mcgim"] = {k: v[()] for k, v in group.items()
                             if isinstance(v, h5py.Dataset) and k not in ("geometry", "geometry_code")}
            item["attrs"] = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in group.attrs.items()}
            origin = frame_origin(group) if "frame_origin" in group.attrs else self.origin(i)
            item["origin"] = origin
            # float32 or quantized (batch --codec quant12|quant16); a coded one needs `gimforge decompress`
            geometry = _read_positions(self.path, group, "local")["positions"]
            item["mcgim"]["geometry"] = geometry + origin if self.frame == "input" else geometry.astype(np.float32)
            return self.transform(item) if self.transform is not None else item
        if self.groups:
            group = g["items"][str(i)]
            item["relief"] = {k: v[()] for k, v in group.items() if isinstance(v, h5py.Dataset)}
            item["attrs"] = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in group.attrs.items()}
            item["distance_scale"] = float(group["distances"].attrs["scale"])
            origin = frame_origin(group) if "frame_origin" in group.attrs else self.origin(i)
            item["origin"] = origin
            if self.frame == "input":
                item["attrs"]["origin"] = np.asarray(item["attrs"]["origin"], dtype=np.float64) + origin
            return self.transform(item) if self.transform is not None else item
        item["data"] = g["data"][i]
        item["origin"] = self.origin(i)
        if self.frame == "input" and self.origins is not None:
            # Channels 0..2 are x, y, z; the sum in float64 (NaN samples stay NaN).
            data = item["data"].astype(np.float64)
            data[:3] += item["origin"][:, None, None]
            item["data"] = data
        if self.has_mask:
            item["mask"] = g["mask"][i]
        if self.has_sample_uv:
            uv = g["sample_uv"][i]
            if not (np.all(uv >= 0.0) and np.all(uv <= 1.0)):  # NaN fails both
                raise ValueError(f"{self.path}: output '{self.output}', item {i} ('{self.names[i]}'): dataset "
                                 "'sample_uv' holds values outside [0, 1]")
            item["sample_uv"] = uv
        if torch is not None:
            item["data"] = torch.from_numpy(item["data"])
            if self.has_mask:
                item["mask"] = torch.from_numpy(item["mask"])
            if self.has_sample_uv:
                item["sample_uv"] = torch.from_numpy(item["sample_uv"])
            item["origin"] = torch.from_numpy(item["origin"])
        return self.transform(item) if self.transform is not None else item

    def __getstate__(self):  # h5py handles cannot be pickled: each worker reopens the file
        state = self.__dict__.copy()
        state["_file"] = None
        return state

    def close(self):
        """Closes the file handle of this process (it reopens on the next access)."""
        if self._file is not None:
            self._file.close()
            self._file = None


def main(argv):
    if len(argv) != 2:
        print(f"usage: {argv[0]} ARCHIVE.h5", file=sys.stderr)
        return 2
    path = argv[1]
    try:
        outputs = batch_outputs(path)
    except (OSError, ValueError, KeyError) as e:
        print(f"load_archive.py: error: {e}", file=sys.stderr)
        return 1
    print(f"{path}: {len(outputs)} output(s){'' if torch is not None else ' (PyTorch not installed: numpy arrays)'}")
    for output, s in outputs.items():
        attrs = ", ".join(f"{k}={v}" for k, v in sorted(s["attributes"].items()))
        print(f"\n[{output}] {attrs}")
        if s["layout"] == "groups":
            print(f"  items: {s['count']}  one group each (items/<k>: relief maps, multi-chart or compressed images)")
        else:
            shape = "x".join(str(d) for d in s["item_shape"]) if s["item_shape"] else "-"
            print(f"  items: {s['count']}  shape (C, H, W): {shape}  mask: {'yes' if s['has_mask'] else 'no'}"
                  f"{'  sample_uv: yes' if s.get('has_sample_uv') else ''}")
        labels = ", ".join(f"{k or '(none)'}: {v}" for k, v in sorted(s["label_counts"].items()))
        print(f"  labels: {labels or '-'}")
        print(f"  failed: {len(s['failed'])}")
        for item in s["failed"]:
            print(f"    {item['name']} ({item['source']}), {item['attempts']} attempt(s): {item['reason']}")
        codec = _strings_attr(s["attributes"].get("codec", ""))
        if s["count"] > 0 and codec in ("auto", "j2k", "wavelet", "j2k-roi"):
            print(f"  coded with '{codec}' (batch --codec): decode with `gimforge decompress {path} -o OUT.h5`, then "
                  "read_image(OUT.h5, ...)")
        elif s["count"] > 0:
            try:
                ds = GimforgeDataset(path, output)
                first = ds[0]
            except (OSError, ValueError, KeyError, IndexError) as e:
                print(f"load_archive.py: error: {e}", file=sys.stderr)
                return 1
            if ds.groups and "relief" in first:
                a = first["attrs"]
                d = first["relief"]["distances"]
                print(f"  first item: {first['name']} label {first['label']} relief map N = {int(a['n'])}, "
                      f"{int(a['grey_cells'])} grey cells, distances {d.dtype} {d.shape}")
            elif "mcgim" in first:
                d = first["mcgim"]["geometry"]
                print(f"  first item: {first['name']} label {first['label']} multi-chart image {d.dtype} {d.shape}")
            else:
                data = np.asarray(first["data"])
                print(f"  first item: {first['name']} label {first['label']} data {data.dtype} {data.shape} "
                      f"range [{np.nanmin(data):.6g}, {np.nanmax(data):.6g}]")
            metrics = ", ".join(f"{k}={v[0]:.6g}" for k, v in sorted(ds.metrics.items())
                                if not np.isnan(v[0]))  # NaN: the item lacks this metric
            print(f"  first item metrics: {metrics or '-'}")
            ds.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
