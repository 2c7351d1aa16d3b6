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

Archives are untrusted (docs/archive.md, "What readers refuse"): every dataset and attribute is checked
before it is read (type, shape against the item's other fields, indices, hard links only, at most 2^33
bytes a read). A damaged archive raises ArchiveError (a ValueError), `ARCHIVE:ITEM: cause`, which the command
prints as one line `load_archive.py: error: ...` (exit 1), control characters escaped. HDF5 1.10 itself crashes
on some crafted files (tests/fuzz/crashes/): open files of unknown origin in a subprocess, or `gimforge ls` them first.

Usage:
    python3 examples/load_archive.py ARCHIVE.h5      # prints outputs, counts, shapes, labels, failures
    python3 examples/load_archive.py --help          # this text

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
import os
import posixpath
import stat
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

# What the loader accepts, as gimforge's readers do (docs/archive.md):
FORMAT_VERSION = 2                # the newest layout it knows ("Versioning")
MAX_READ_BYTES = 1 << 33          # the most one read allocates (h5::kMaxReadBytes)
MAX_COUNT = 1 << 40               # items of an output (io/batch_archive.cpp)
MAX_GIM_SIDE = (1 << 14) + 1      # n of a geometry image (io/gim_archive.h)
MAX_SPHERE_N = 4096               # tessellation number of a spherical image (jobs/method.h)
MAX_MCGIM_SAMPLES = 1 << 26       # W·H of a multi-chart image (io/mcgim_archive.h)
MAX_CHARTS = 1 << 20              # its charts (io/mcgim_archive.cpp)
MAX_UNITS_PER_SIDE = 1 << 20      # a sideband's units_per_side (kernels/gim/geometry_image.h)
MAX_RELIEF_SIDE = 1024            # a relief map's grid n and texture T (io/relief_archive.cpp)
MAX_ORIGIN = 1e12                 # |frame_origin| ("Local frame and origin")
MAX_COORDINATE = 1e18             # |sample| of an image: no mesh gimforge reads lies farther (io/ply_ranges.h)
FLOAT32_MAX = float(np.finfo(np.float32).max)
POSITIVE = float(np.finfo(np.float64).tiny)  # lower bound of a value that must be > 0
SPHERE_SHAPES = {"octa": lambda n: (2 * n + 1, 2 * n + 1), "flat-octa": lambda n: (2 * n + 1, 2 * n + 1),
                 "tetra": lambda n: (n + 1, 2 * n), "cube": lambda n: (6 * (n + 1), n + 1)}  # (H, W) at n


class ArchiveError(ValueError):
    """A damaged or crafted archive: str(error) is "ARCHIVE:/path: cause" (`item`, `cause`); a ValueError, as
    the loader's refusals always were."""

    def __init__(self, item, cause):
        super().__init__(item, cause)  # both in args, so that the error pickles (DataLoader workers)
        self.item, self.cause = item, cause

    def __str__(self):
        return f"{self.item}: {self.cause}"


def _where(obj, name=""):
    """"ARCHIVE:/path" of h5py object `obj` (or of its member `name`), for ArchiveError."""
    return f"{obj.file.filename}:{posixpath.join(obj.name, name) if name else obj.name}"


def _open(path):
    """The archive at `path`, opened read-only. A path that is not a regular file (opening a FIFO would wait
    for a writer), a file HDF5 does not open and a format_version newer than FORMAT_VERSION are refused."""
    if not stat.S_ISREG(os.stat(path).st_mode):
        raise ArchiveError(path, "is not a regular file")
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise ArchiveError(path, f"does not open as HDF5: {' '.join(str(e).split())}") from None
    try:
        if "format_version" in f.attrs:
            _value(f, "@format_version", "int", (), 1, FORMAT_VERSION)
    except ArchiveError:
        f.close()
        raise
    return f


def _child(group, name, kind=None, optional=False):
    """group[name] (`name` may have several parts) through hard links only (no soft or external link, no data
    kept in other files), of `kind` (h5py.Group or h5py.Dataset) when given; absent: None if `optional`."""
    obj = group
    for part in name.strip("/").split("/"):
        if not isinstance(obj, h5py.Group):
            raise ArchiveError(_where(obj), f"is not a group (looking for '{part}' in it)")
        link = obj.get(part, getlink=True)
        if link is None:
            if optional:
                return None
            raise ArchiveError(_where(obj), f"has no '{part}'")
        if isinstance(link, h5py.SoftLink):
            raise ArchiveError(_where(obj, part), f"is a soft link (to '{link.path}'); only hard links are followed")
        if isinstance(link, h5py.ExternalLink):
            raise ArchiveError(_where(obj, part), f"is an external link (to {link.filename}:{link.path}); only hard "
                                                  "links are followed")
        if not isinstance(link, h5py.HardLink):
            raise ArchiveError(_where(obj, part), "is a link of an unknown kind; only hard links are followed")
        obj = obj[part]
    if kind is not None and not isinstance(obj, kind):
        raise ArchiveError(_where(obj), f"is not a {'group' if kind is h5py.Group else 'dataset'}")
    if isinstance(obj, h5py.Dataset) and (obj.is_virtual or obj.external):
        raise ArchiveError(_where(obj), "keeps its data in other files (a virtual dataset or external storage); only "
                                        "data stored in the archive is read")
    return obj


def _present(group, name):  # whether `group` holds `name` (no soft or external link, as _child)
    return _child(group, name, optional=True) is not None


def _type_ok(dt, dtype):
    if dtype in ("str", "decimal"):
        return h5py.check_string_dtype(dt) is not None
    if dtype == "int":
        return dt.kind in "iu"
    return any(dt.kind == np.dtype(t).kind and dt.itemsize == np.dtype(t).itemsize
               for t in (dtype if isinstance(dtype, tuple) else (dtype,)))  # either byte order


def _type_text(dtype):
    names = {"str": "strings", "decimal": "a string holding a decimal integer", "int": "integers"}
    if isinstance(dtype, np.dtype):
        return "strings" if h5py.check_string_dtype(dtype) is not None else dtype.name
    return names.get(dtype) or " or ".join(np.dtype(t).name for t in (dtype if isinstance(dtype, tuple) else (dtype,)))


def _shape_text(shape):
    if shape is None:
        return "(no value)"
    dims = ["*" if d is None else f"{d.start}..{d.stop - 1}" if isinstance(d, range) else str(d) for d in shape]
    return f"({dims[0]},)" if len(dims) == 1 else f"({', '.join(dims)})"


def _check_type_shape(where, what, dt, shape, dtype, want):
    """Refuses `what` of element type `dt` and shape `shape` unless they are `dtype` and `want` (see _value)."""
    if not _type_ok(dt, dtype):
        raise ArchiveError(where, f"{what} holds {_type_text(dt)}, expected {_type_text(dtype)}")
    if shape is None or len(shape) != len(want) or not all(
            w is None or (d in w if isinstance(w, range) else d == w) for d, w in zip(shape, want)):
        raise ArchiveError(where, f"{what} has shape {_shape_text(shape)}, expected {_shape_text(want)}")


def _check_range(where, what, values, lo, hi):
    """Refuses `what` unless every one of `values` lies in [lo, hi] (and is finite, for floats)."""
    v = np.asarray(values)
    ok = (v >= lo) & (v <= hi) & (np.isfinite(v) if v.dtype.kind == "f" else True)
    if ok.all():
        return
    k = int(np.argmin(ok.reshape(-1)))  # the first value refused
    index = tuple(int(x) for x in np.unravel_index(k, v.shape))
    bad = v.reshape(-1)[k].item()
    head = f"{what} = {bad}" if v.ndim == 0 else f"{what} holds {bad} at {index[0] if v.ndim == 1 else index}"
    if not np.isfinite(bad):
        raise ArchiveError(where, f"{head}, which is not finite")
    low = "(0" if lo == POSITIVE else f"[{lo:g}" if isinstance(lo, float) else f"[{lo}"
    raise ArchiveError(where, f"{head}, outside {low}, {f'{hi:g}' if isinstance(hi, float) else hi}]")


def _check_stored(where, what, ds):
    """Refuses dataset `ds` unless the file stores every value it declares: an unwritten chunk (or contiguous
    dataset) reads as fill values, so a declared shape would cost the file nothing and the reader its size."""
    if ds.chunks is None:
        stored, declared, unit = ds.id.get_storage_size(), ds.size * ds.dtype.itemsize, "bytes"
    else:
        chunks = [-(-extent // chunk) for extent, chunk in zip(ds.shape, ds.chunks)]
        stored, declared, unit = ds.id.get_num_chunks(), int(np.prod(chunks, dtype=object)), "chunks"
    if stored < declared:
        raise ArchiveError(where, f"{what} stores {stored} of its {declared} {unit} (the rest would read as fill "
                                  "values)")


def _dataset(group, name, dtype, shape):
    """The dataset group[name] (through _child), its element type and shape checked as _value does; nothing is
    read (for a stack read one item at a time)."""
    ds = _child(group, name, h5py.Dataset)
    _check_type_shape(_where(group), f"dataset '{name}'", ds.dtype, ds.shape, dtype, shape)
    return ds


def _value(obj, name, dtype, shape=(), lo=None, hi=None):
    """The value of `name` in `obj`, checked before it is read: "@key" is obj's attribute `key`, any other name
    the dataset obj[name] (hard links only, see _child). Its element type must be `dtype`: a numpy type ("f4",
    "u2", ...; several in a tuple), "int" (any integer), "str" (strings) or "decimal" (a string holding a
    decimal integer, returned as int); its shape `shape`, one entry per dimension: an int, a range of allowed
    extents or None (any); and a dataset read at most MAX_READ_BYTES. With `lo` and `hi` every value must lie
    in [lo, hi] (and be finite, for floats). Returns a Python scalar for a scalar attribute, a list of str for
    a string dataset, else a numpy array."""
    where, key = _where(obj), name[1:] if name.startswith("@") else None
    what = f"attribute {key}" if key else f"dataset '{name}'"
    try:
        if key:
            if key not in obj.attrs:
                raise ArchiveError(where, f"has no attribute '{key}'")
            attr = obj.attrs.get_id(key)
            _check_type_shape(where, what, attr.dtype, attr.shape, dtype, shape)
            value = obj.attrs[key]
        else:
            ds = _dataset(obj, name, dtype, shape)
            size = int(np.prod(ds.shape, dtype=object)) * ds.dtype.itemsize
            if size > MAX_READ_BYTES:
                raise ArchiveError(where, f"{what} has shape {ds.shape}: {size} bytes, more than the loader reads at "
                                          "once (2^33 bytes)")
            _check_stored(where, what, ds)
            value = ds.asstr()[()] if dtype in ("str", "decimal") else ds[()]
        if isinstance(value, bytes):  # a fixed-length string attribute
            value = value.decode()
    except (OSError, UnicodeDecodeError) as e:  # damaged metadata or data, a string that is not UTF-8
        raise ArchiveError(where, f"{what} does not read: {' '.join(str(e).split())}") from None
    if dtype in ("str", "decimal") and isinstance(value, np.ndarray):
        value = value.tolist()
    if dtype == "decimal":
        if not (value.isascii() and value.isdigit() and len(value) <= 18):
            raise ArchiveError(where, f"{what} = '{value}' is not a decimal integer")
        value = int(value)
    elif isinstance(value, np.generic):
        value = value.item()
    if lo is not None:
        _check_range(where, what, value, lo, hi)
    return value


def _read_known(group, specs):
    """{name: value} of the datasets of `group` that `specs` ({name: _value arguments}) knows (others ignored)."""
    return {name: _value(group, name, *specs[name]) for name in group.keys() if name in specs}


def _method(group):  # the `method` attribute of an item's group, as a str ("" when absent)
    return _value(group, "@method", "str") if "method" in group.attrs else ""


def _strings_attr(value):
    return value.decode() if isinstance(value, bytes) else value


def frame_origin(group):
    """The `frame_origin` attribute of a representation group (/gim/<name>, /spherical/<name>,
    /relief/<name> or a batch's items/<k>) as a float64 array (3,): what to add to its positions to get the
    input mesh's coordinates; zeros when absent (an archive written before the local frame). Refused unless 3
    finite float64 values within ±1e12."""
    if "frame_origin" not in group.attrs:
        return np.zeros(3)
    return _value(group, "@frame_origin", "f8", (3,), -MAX_ORIGIN, MAX_ORIGIN)


def _sphere_shape(group, domain, n):
    if domain not in SPHERE_SHAPES:
        raise ArchiveError(_where(group), f"attribute domain = '{domain}' is not one of {', '.join(SPHERE_SHAPES)}")
    return SPHERE_SHAPES[domain](n)


def _stack_shape(g):
    """(H, W) of the images of a stacked output g (/batch/<output>), from its string attributes: method gim
    and size, or method sphere, domain and n."""
    method = _value(g, "@method", "str")
    if method == "gim":
        n = _value(g, "@size", "decimal", (), 2, MAX_GIM_SIDE)
        return n, n
    if method == "sphere":
        return _sphere_shape(g, _value(g, "@domain", "str"), _value(g, "@n", "decimal", (), 1, MAX_SPHERE_N))
    raise ArchiveError(_where(g), f"attribute method = '{method}': an output of stacked images is gim or sphere")


def _image_shape(g):
    """(H, W) of the positions of image group g (a geometry, spherical or multi-chart image), from its
    attributes: size; domain and n; width and height."""
    method = _method(g)
    if method == "sphere":
        return _sphere_shape(g, _value(g, "@domain", "str"), _value(g, "@n", "int", (), 1, MAX_SPHERE_N))
    if method == "mcgim":
        w, h = (_value(g, key, "int", (), 1, MAX_MCGIM_SAMPLES) for key in ("@width", "@height"))
        if w * h > MAX_MCGIM_SAMPLES:
            raise ArchiveError(_where(g), f"{w} x {h} samples exceed the limit of 2^26")
        return h, w
    if "size" in g.attrs:
        n = _value(g, "@size", "int", (), 2, MAX_GIM_SIDE)
        return n, n
    shape = _child(g, "geometry", h5py.Dataset).shape or ()  # an image written without `size`
    if len(shape) != 3 or shape[0] != shape[1] or not 2 <= shape[0] <= MAX_GIM_SIDE:
        raise ArchiveError(_where(g), f"dataset 'geometry' has shape {_shape_text(shape)}, expected (n, n, 3) with "
                                      f"2 <= n <= {MAX_GIM_SIDE}")
    return shape[0], shape[0]


def read_image(path, item, frame="input"):
    """One geometry image, spherical or multi-chart geometry image of an archive (`item` = "gim/NAME",
    "spherical/NAME" or "mcgim/NAME")
    as a dict {"positions": (H, W, 3), "mask": (H, W) bool or None, "storage": str}. Positions are float64 in the
    input's coordinates (frame="input") or the stored local frame (frame="local"); NaN where the mask is 0.
    Reads what `convert` writes (float32) and what `gimforge compress --codec quant12|quant16` writes (uint16
    with per-axis `scale` and `offset`: offset + scale * q). Items coded with j2k or wavelet
    (`geometry_code`, docs/archive.md "Compressed items") need gimforge's decoders and, for geometry images,
    the fusing of the cut from the sideband: decode them with `gimforge decompress ARCHIVE -o OUT.h5` and read
    OUT.h5. A damaged item raises ArchiveError."""
    if frame not in FRAMES:
        raise ValueError(f"frame must be one of {FRAMES}, not {frame!r}")
    with _open(path) as f:
        g = _child(f, item, optional=True) if item.strip("/") else None
        if not isinstance(g, h5py.Group):
            raise KeyError(f"{path}: no item '{item}'")
        if item.strip("/").startswith("relief/") or _method(g) == "relief":
            raise ValueError(f"{path}: '{item}' is a relief map, not an image of positions: read it with "
                             "GimforgeDataset, or as docs/archive.md (\"Relief maps\") describes")
        return _read_positions(path, g, frame)


def _read_positions(path, g, frame):
    """read_image() of an open group (/gim/<name>, /spherical/<name>, /mcgim/<name>, or a batch item items/<k>)."""
    code = _child(g, "geometry_code", optional=True)
    if code is not None:
        codec = _value(code, "@codec", "str") if "codec" in code.attrs else "?"
        raise ValueError(f"{path}:{g.name} is coded with '{codec}': decode it with `gimforge decompress {path} -o OUT.h5` "
                         "and read OUT.h5")
    h, w = _image_shape(g)
    q = _value(g, "geometry", ("f4", "u2"), (h, w, 3))
    if q.dtype.kind == "f":  # as stored: quantization attributes on it mean a damaged or edited item
        if {"bits", "scale", "offset"} & set(_child(g, "geometry").attrs):
            raise ArchiveError(_where(g, "geometry"), "is float32 but carries quantization attributes")
        positions, storage = q.astype(np.float64), "float32"
    else:
        positions, bits = _dequantize(path, g.name + "/geometry", _child(g, "geometry"), q)
        storage = f"quant{bits}"
    mask = _value(g, "mask", "u1", (h, w), 0, 1) == 1 if _present(g, "mask") else None
    # Every sample of a geometry image is finite, and every defined one (mask 1) of the others.
    defined = positions if mask is None else np.where(mask[..., None], positions, 0)
    _check_range(_where(g), "dataset 'geometry'", defined, -MAX_COORDINATE, MAX_COORDINATE)
    if mask is not None:
        positions[~mask] = np.nan
    if frame == "input":
        positions = positions + frame_origin(g)
    return {"positions": positions, "mask": mask, "storage": storage}


def _dequantize(path, name, ds, q):
    """offset + scale * q of a quantized (H, W, 3) dataset, with the checks gimforge's readers make
    (io/coded_image.cpp): `bits` an integer 8, 12 or 16 (absent: 16), every q < 2^bits, `scale` and `offset`
    float64 (1 or 3 values), scale > 0 and offset + scale * (2^bits - 1) within float32. Returns (positions
    rounded to float32 as gimforge rounds them, bits)."""
    def bad(what):
        return ArchiveError(f"{path}:{name}", what)
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
    return (offset + scale * q.astype(np.float64)).astype(np.float32).astype(np.float64), bits


def _check_items(g, count):
    """The group `items` of output g must hold exactly the groups 0..count-1, each through a hard link."""
    items = _child(g, "items", h5py.Group)
    names = list(items.keys())
    if len(names) != count or set(names) != {str(k) for k in range(count)}:
        raise ArchiveError(_where(items), f"must hold exactly the groups 0..{count - 1} (it holds {len(names)} "
                                          "entries)")
    for name in names:
        _child(items, name, h5py.Group)


def _read_output(g):
    """What batch_outputs() and GimforgeDataset read of output group g (/batch/<output>), every dataset checked
    against the count N, the failures F and the image size the attributes name before it is read (the images
    themselves are not read here): a dict with count, groups, stack (the shape of `data`), has_mask,
    has_sample_uv, names, sources, indices, labels (label_index), label_names, metrics, origins, failed and
    attributes."""
    n = _value(g, "@count", "int", (), 0, MAX_COUNT)
    n_failed = _value(g, "@failed_count", "int", (), 0, MAX_COUNT)
    s = {"count": n, "groups": _present(g, "items"), "stack": None, "has_mask": False, "has_sample_uv": False}
    if s["groups"]:
        _check_items(g, n)
    else:
        h, w = _stack_shape(g) if n else (None, None)  # an output whose every item failed is (0, 0, 0, 0)
        data = _dataset(g, "data", "f4", (n, 3 if n else None, h, w))
        _check_stored(_where(g), "dataset 'data'", data)
        s["stack"] = data.shape
        for key, dtype, channels in (("mask", "u1", 1), ("sample_uv", "f4", 2)):
            s["has_" + key] = _present(g, key)
            if s["has_" + key]:
                _check_stored(_where(g), f"dataset '{key}'", _dataset(g, key, dtype, (n, channels, h, w)))
    s["names"] = _value(g, "names", "str", (n,))
    bad = [x for x in s["names"] if {"", ".", ".."} & set(x.split("/"))]  # control characters: escaped (_say)
    if bad or len(set(s["names"])) != n:  # what gimforge's readers take: distinct relative paths ("chair/0001")
        raise ArchiveError(_where(g), f"dataset 'names' holds {ascii(bad[0]) if bad else 'a name twice'}, not {n} "
                                      "distinct relative paths without '.' or '..' parts")
    s["sources"] = _value(g, "sources", "str", (n,))
    s["indices"] = _value(g, "index", "i8", (n,), 0, 2 ** 63 - 1)
    if np.any(np.diff(s["indices"]) <= 0):
        raise ArchiveError(_where(g), "dataset 'index' is not increasing")
    s["label_names"] = _value(g, "label_names", "str", (range(n + n_failed + 1),))
    s["labels"] = _value(g, "label_index", "i4", (n,), -1, len(s["label_names"]) - 1)
    metrics = _child(g, "metrics", h5py.Group)
    s["metrics"] = {key: _value(metrics, key, "f8", (n,)) for key in metrics.keys()}
    s["origins"] = None  # (N, 3) float64, or None for archives written before the local frame
    if 0 < sum(key in s["metrics"] for key in ORIGIN_METRICS) < 3:  # else read in the local frame as input's
        raise ArchiveError(_where(metrics), "the metrics hold only some of " + ", ".join(ORIGIN_METRICS))
    if all(key in s["metrics"] for key in ORIGIN_METRICS):
        s["origins"] = np.stack([_value(metrics, key, "f8", (n,), -MAX_ORIGIN, MAX_ORIGIN) for key in ORIGIN_METRICS],
                                axis=1)
    failed = _child(g, "failed", h5py.Group)
    columns = [_value(failed, key, "str", (n_failed,)) for key in ("names", "sources", "reasons")]
    s["failed"] = [{"name": name, "source": source, "reason": reason, "attempts": int(attempts)}
                   for name, source, reason, attempts in zip(*columns, _value(failed, "attempts", "i4", (n_failed,)))]
    s["attributes"] = {k: _strings_attr(v) for k, v in g.attrs.items()}
    return s


def _outputs(f):
    """The /batch group of open archive f."""
    batch = _child(f, BATCH_GROUP, h5py.Group, optional=True)
    if batch is None:
        raise ValueError(f"{f.filename}: not a batch archive (no /{BATCH_GROUP} group); a convert archive's images "
                         "load with read_image(path, 'gim/NAME')")
    return batch


def batch_outputs(path):
    """The outputs of the batch archive at `path`: {output: summary dict}, sorted by name.

    Each summary holds: count (N), layout ("stacked" images, or "groups": relief maps,
    multi-chart images and compressed outputs, one group per item), item_shape
    ((C, H, W), or None when N is 0 or the items are groups), has_mask, names,
    label_names, label_counts ({label: items}, "" for unlabelled), metric_keys, failed (a list of
    {"name", "source", "reason", "attempts"}) and attributes (the group's attributes: method, size, ...).
    A damaged archive raises ArchiveError.
    """
    with _open(path) as f:
        batch = _outputs(f)
        summaries = {}
        for output in sorted(batch.keys()):
            s = _read_output(_child(batch, output, h5py.Group))
            counts = {}
            for k in s["labels"]:
                label = s["label_names"][k] if k >= 0 else ""
                counts[label] = counts.get(label, 0) + 1
            summaries[output] = {
                "count": s["count"], "layout": "groups" if s["groups"] else "stacked",
                "item_shape": tuple(s["stack"][1:]) if s["stack"] and s["count"] > 0 else None,
                **{key: s[key] for key in ("has_mask", "has_sample_uv", "names", "label_names")},
                "label_counts": counts, "metric_keys": sorted(s["metrics"]), "failed": s["failed"],
                "attributes": s["attributes"]}
        return summaries


def _relief_datasets(group):
    """The datasets of relief item `group`, each checked against its attributes n, texture, grey_cells and
    layers (docs/archive.md, "Relief maps") before it is read, and its indices against what they index."""
    n = _value(group, "@n", "int", (), 1, MAX_RELIEF_SIDE)
    t = _value(group, "@texture", "int", (), 2, MAX_RELIEF_SIDE)
    cells = _value(group, "@grey_cells", "int", (), 1, n ** 3)
    layers = _value(group, "@layers", "int", (), 1, 6 * cells)
    _value(group, "@origin", "f8", (3,), -FLOAT32_MAX, FLOAT32_MAX)
    _value(group, "@cell_size", "f8", (), POSITIVE, FLOAT32_MAX)
    return _read_known(group, {
        "cells": ("u4", (cells, 3), 0, n - 1),
        "external_faces": ("u1", (cells,), 0, 63),
        "case": ("u1", (cells,), 0, 9),
        "projection": ("u1", (cells,), 0, 3),
        "domain_faces": ("u1", (cells,), 0, 63),
        "projection_params": ("f8", (cells, 6), -np.inf, np.inf),
        "layer_cell": ("u4", (layers,), 0, cells - 1),
        "layer_face": ("u1", (layers,), 0, 5),
        "distances": ("u2", (layers, t, t)),
        "normals": ("i1", (layers, t, t, 3), -127, 127),
        "colors": ("u1", (layers, t, t, 3)),
        "grid_levels": ("i8", (range(1, MAX_RELIEF_SIDE + 1), 5)),
    })


def _mcgim_datasets(group):
    """The datasets of multi-chart item `group` but its positions, each checked against its attributes width,
    height and num_charts before it is read, and chart ids and zipper rows against what they index."""
    h, w = _image_shape(group)
    charts = _value(group, "@num_charts", "int", (), 1, MAX_CHARTS)
    return _read_known(group, {
        "mask": ("u1", (h, w), 0, 1),
        "chart": ("i4", (h, w), -1, charts - 1),
        "zipper": ("i4", (range(h * w + 1), 2), 0, h * w - 1),
        "normals": ("f4", (h, w, 3)),
        "chart_stretch": ("f8", (charts,)),
        "zipper_diagonals": ("u1", (range(h * w // 8 + 2),)),
    })


def _as_tensors(item):
    """With PyTorch installed, item's arrays data, mask, sample_uv and origin become tensors (in place)."""
    for key in ("data", "mask", "sample_uv", "origin"):
        if torch is not None and key in item:
            item[key] = torch.from_numpy(item[key])


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

    Every table is checked when the dataset is made and every item when it is read (see the module's
    description); a damaged archive raises ArchiveError, a ValueError naming the file, the item and the cause.
    """

    def __init__(self, path, output=None, transform=None, frame="input"):
        if frame not in FRAMES:
            raise ValueError(f"frame must be one of {', '.join(FRAMES)}, not {frame!r}")
        self.path = str(path)
        self.transform = transform
        self.frame = frame
        self._file = None
        with _open(self.path) as f:
            batch = _outputs(f)
            outputs = sorted(batch.keys())
            if output is None:
                if len(outputs) != 1:
                    raise ValueError(f"{self.path}: choose an output: {', '.join(outputs)}")
                output = outputs[0]
            if output not in outputs:
                raise KeyError(f"{self.path}: no output '{output}' (has: {', '.join(outputs)})")
            s = _read_output(_child(batch, output, h5py.Group))
            self.output = output
            # as _read_output reads them; origins: (N, 3) float64, or None for archives older than the local frame
            for key in ("names", "sources", "indices", "labels", "label_names", "has_mask", "has_sample_uv", "groups",
                        "metrics", "attributes", "origins"):
                setattr(self, key, s[key])
            self.item_shape = None if self.groups else tuple(s["stack"][1:])
            if not self.has_sample_uv and _strings_attr(self.attributes.get("sampling")) == "adaptive" \
                    and not self.groups and s["count"] > 0:  # an output whose every item failed has none
                raise ArchiveError(_where(f, f"{BATCH_GROUP}/{output}"), "was converted with adaptive sampling but "
                                                                          "has no dataset 'sample_uv'")

    def origin(self, i):
        """The frame origin of item i, (3,) float64 (zeros when the archive has none)."""
        return np.zeros(3) if self.origins is None else self.origins[i].copy()

    def sideband(self, i):
        """Geometry-image outputs: item i's sideband, (q, 3) int32 rows label, start_unit, units (the cut's
        gluing, as /gim/<name>/sideband holds it; docs/archive.md), with `units_per_side`: from the output's
        stacked table, or from items/<k>/sideband in a compressed output (batch --codec); None when the output
        or the item has none (archives written before 2026-12-06). Not part of __getitem__: its length
        differs from item to item, which a DataLoader cannot stack. Raises IndexError for an index out of
        range and ArchiveError (a ValueError) naming the file and output for damaged tables."""
        n, i = len(self), self._index(i)
        g = self._group()
        if not _present(g, "sideband") and not _present(g, "sideband_offsets"):
            item = _child(g, f"items/{i}", h5py.Group) if self.groups else None
            if item is None or not _present(item, "sideband"):
                return None
            units = _value(item, "@units_per_side", "int", (), 1, MAX_UNITS_PER_SIDE)
            return _value(item, "sideband", "i4", (range(4 * units + 1), 3)), units
        table = _dataset(g, "sideband", "i4", (None, 3))
        o = _value(g, "sideband_offsets", "i8", (n + 1,), 0, table.shape[0])
        if o[0] != 0 or o[-1] != table.shape[0] or np.any(np.diff(o) < 0):
            raise ArchiveError(_where(g), "dataset 'sideband_offsets' does not index 'sideband' (0 first, never "
                                          "decreasing, its rows last)")
        start, end = int(o[i]), int(o[i + 1])
        if start == end:
            return None
        units = _value(table, "@units_per_side", "int", (), 1, MAX_UNITS_PER_SIDE)
        if end - start > 4 * units:
            raise ArchiveError(_where(g), f"item {i}'s sideband has {end - start} rows, more than 4 * units_per_side")
        return table[start:end], units

    def __len__(self):
        return len(self.names)

    def _group(self):
        if self._file is None:
            self._file = _open(self.path)
        return _child(self._file, f"{BATCH_GROUP}/{self.output}", h5py.Group)

    def _index(self, i):
        """Item index i (negative from the end) checked against the items."""
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise TypeError(f"item index must be an integer, not {type(i).__name__}")
        n, asked = len(self), int(i)
        i = asked + (n if asked < 0 else 0)
        if not 0 <= i < n:
            raise IndexError(f"item {asked} out of range for {n} items")
        return i

    def __getitem__(self, i):
        n, i = len(self), self._index(i)
        g = self._group()
        item = {"label": int(self.labels[i]), "name": self.names[i], "index": int(self.indices[i])}
        if self.groups:
            group = _child(g, f"items/{i}", h5py.Group)
            if "source" in group.attrs and _value(group, "@source", "str") != self.sources[i]:
                raise ArchiveError(_where(group), f"holds the item converted from '{_value(group, '@source', 'str')}', "
                                                  f"but the output's sources name '{self.sources[i]}' for it")
            method = _method(group)
            if method in ("gim", "sphere"):
                # batch --codec: a quantized item is read here; a coded one needs `gimforge decompress`
                r = _read_positions(self.path, group, self.frame)
                data = np.ascontiguousarray(np.moveaxis(r["positions"], -1, 0))  # (3, H, W) like the stacked outputs
                item["data"] = data if self.frame == "input" else data.astype(np.float32)
                item["origin"] = frame_origin(group)
                if r["mask"] is not None:
                    item["mask"] = r["mask"][None].astype(np.uint8)
                _as_tensors(item)
            elif method == "mcgim":
                item["mcgim"] = _mcgim_datasets(group)
                item["attrs"] = {k: _strings_attr(v) for k, v in group.attrs.items()}
                item["origin"] = origin = frame_origin(group) if "frame_origin" in group.attrs else self.origin(i)
                # float32 or quantized (batch --codec quant12|quant16); a coded one needs `gimforge decompress`
                geometry = _read_positions(self.path, group, "local")["positions"]
                item["mcgim"]["geometry"] = geometry + origin if self.frame == "input" else geometry.astype(np.float32)
            elif method == "relief":
                item["relief"] = _relief_datasets(group)
                item["attrs"] = {k: _strings_attr(v) for k, v in group.attrs.items()}
                item["distance_scale"] = _value(_child(group, "distances"), "@scale", "f8", (), POSITIVE, FLOAT32_MAX)
                item["origin"] = origin = frame_origin(group) if "frame_origin" in group.attrs else self.origin(i)
                if self.frame == "input":
                    item["attrs"]["origin"] = np.asarray(item["attrs"]["origin"], dtype=np.float64) + origin
            else:
                raise ArchiveError(_where(group), f"attribute method = '{method}' is not gim, sphere, mcgim or relief")
            return self.transform(item) if self.transform is not None else item
        shape = (n,) + self.item_shape
        item["data"] = _dataset(g, "data", "f4", shape)[i]
        item["origin"] = self.origin(i)
        defined = item["data"]
        if self.has_mask:
            item["mask"] = _dataset(g, "mask", "u1", (n, 1) + shape[2:])[i]
            _check_range(_where(g), f"dataset 'mask' of item {i} ('{self.names[i]}')", item["mask"], 0, 1)
            defined = np.where(item["mask"] == 1, defined, 0)
        _check_range(_where(g), f"dataset 'data' of item {i} ('{self.names[i]}')", defined, -MAX_COORDINATE, MAX_COORDINATE)
        if self.frame == "input" and self.origins is not None:
            # Channels 0..2 are x, y, z; the sum in float64 (NaN samples stay NaN).
            data = item["data"].astype(np.float64)
            data[:3] += item["origin"][:, None, None]
            item["data"] = data
        if self.has_sample_uv:
            item["sample_uv"] = _dataset(g, "sample_uv", "f4", (n, 2) + shape[2:])[i]
            _check_range(_where(g), f"dataset 'sample_uv' of item {i} ('{self.names[i]}')", item["sample_uv"], 0.0, 1.0)
        _as_tensors(item)
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


# What a damaged or unreadable archive raises (h5py also OSError, KeyError, RuntimeError, TypeError; MemoryError).
ERRORS = (OSError, ValueError, KeyError, IndexError, TypeError, RuntimeError, MemoryError)


def _say(text, file=sys.stdout):
    """Prints `text` with control characters escaped (names come from the file: no forged lines, no escapes)."""
    print("".join(c if c == " " or c.isprintable() else ascii(c)[1:-1] for c in str(text)), file=file)


def _error(path, e):
    """Prints `e` as one line `load_archive.py: error: ARCHIVE...: cause` and returns the exit status 1."""
    text = str(e.args[0]) if isinstance(e, KeyError) and e.args else str(e)
    _say(f"load_archive.py: error: {text if text.startswith(path) else f'{path}: {text}'}", file=sys.stderr)
    return 1


def main(argv):
    if len(argv) == 2 and argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0
    if len(argv) != 2:
        print(f"usage: {argv[0]} ARCHIVE.h5", file=sys.stderr)
        return 2
    path = argv[1]
    try:
        outputs = batch_outputs(path)
    except ERRORS as e:
        return _error(path, e)
    _say(f"{path}: {len(outputs)} output(s){'' if torch is not None else ' (PyTorch not installed: numpy arrays)'}")
    for output, s in outputs.items():
        attrs = ", ".join(f"{k}={v}" for k, v in sorted(s["attributes"].items()))
        print()
        _say(f"[{output}] {attrs}")
        if s["layout"] == "groups":
            _say(f"  items: {s['count']}  one group each (items/<k>: relief maps, multi-chart or compressed images)")
        else:
            shape = "x".join(str(d) for d in s["item_shape"]) if s["item_shape"] else "-"
            _say(f"  items: {s['count']}  shape (C, H, W): {shape}  mask: {'yes' if s['has_mask'] else 'no'}"
                  f"{'  sample_uv: yes' if s.get('has_sample_uv') else ''}")
        labels = ", ".join(f"{k or '(none)'}: {v}" for k, v in sorted(s["label_counts"].items()))
        _say(f"  labels: {labels or '-'}")
        print(f"  failed: {len(s['failed'])}")
        for item in s["failed"]:
            _say(f"    {item['name']} ({item['source']}), {item['attempts']} attempt(s): {item['reason']}")
        codec = _strings_attr(s["attributes"].get("codec", ""))
        if s["count"] > 0 and codec in ("auto", "j2k", "wavelet", "j2k-roi"):
            _say(f"  coded with '{codec}' (batch --codec): decode with `gimforge decompress {path} -o OUT.h5`, then "
                  "read_image(OUT.h5, ...)")
        elif s["count"] > 0:
            try:
                ds = GimforgeDataset(path, output)
                first = ds[0]
            except ERRORS as e:
                return _error(path, e)
            if ds.groups and "relief" in first:
                a = first["attrs"]
                d = first["relief"]["distances"]
                _say(f"  first item: {first['name']} label {first['label']} relief map N = {int(a['n'])}, "
                      f"{int(a['grey_cells'])} grey cells, distances {d.dtype} {d.shape}")
            elif "mcgim" in first:
                d = first["mcgim"]["geometry"]
                _say(f"  first item: {first['name']} label {first['label']} multi-chart image {d.dtype} {d.shape}")
            else:
                data = np.asarray(first["data"])
                _say(f"  first item: {first['name']} label {first['label']} data {data.dtype} {data.shape} "
                      f"range [{np.nanmin(data):.6g}, {np.nanmax(data):.6g}]")
            metrics = ", ".join(f"{k}={v[0]:.6g}" for k, v in sorted(ds.metrics.items())
                                if not np.isnan(v[0]))  # NaN: the item lacks this metric
            _say(f"  first item metrics: {metrics or '-'}")
            ds.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
