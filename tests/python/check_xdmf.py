"""check_xdmf.py WRITER OUT.h5: runs WRITER (write_xdmf_sample) and checks the XDMF sidecar it writes
against the archive with h5py: every HDF5 reference names an existing dataset of the stated shape, every
hyperslab lies inside its dataset and yields the stated count, every grid's geometry holds 3 values per
point of its topology, and the grids are exactly the structured items of the archive (relief maps none)."""
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np


def dims(text):
    return tuple(int(x) for x in text.split())


def resolve(item, f):
    """The values a DataItem yields, read with h5py."""
    if item.get("ItemType") == "HyperSlab":
        spec, source = list(item)
        numbers = np.array([int(x) for x in spec.text.split()]).reshape(3, -1)
        start, stride, count = numbers
        data = resolve(source, f)
        assert np.all(start + (count - 1) * stride < np.array(data.shape)), "hyperslab outside its dataset"
        slices = tuple(slice(s, s + c * st, st) for s, st, c in zip(start, stride, count))
        out = data[slices]
        assert out.shape == dims(item.get("Dimensions")), (out.shape, item.get("Dimensions"))
        return out
    assert item.get("Format") == "HDF", item.attrib
    file_name, path = item.text.strip().split(":", 1)
    assert file_name == f.filename.split("/")[-1], file_name
    ds = f[path]
    assert ds.shape == dims(item.get("Dimensions")), (path, ds.shape, item.get("Dimensions"))
    return ds[()]


def main():
    writer, out = sys.argv[1], sys.argv[2]
    sidecar = subprocess.run([writer, out], check=True, capture_output=True, text=True).stdout.strip()
    assert sidecar.endswith(".xmf"), sidecar
    root = ET.parse(sidecar).getroot()
    assert root.tag == "Xdmf" and root.get("Version") == "3.0"
    names = []
    with h5py.File(out, "r") as f:
        for grid in root.iter("Grid"):
            if grid.get("GridType") != "Uniform":
                continue
            names.append(grid.get("Name"))
            topology = grid.find("Topology")
            assert topology.get("TopologyType") == "2DSMesh"
            rows, cols = dims(topology.get("Dimensions"))
            geometry = grid.find("Geometry")
            values = [resolve(item, f) for item in geometry.findall("DataItem")]
            if geometry.get("GeometryType") == "XYZ":
                assert len(values) == 1 and values[0].size == rows * cols * 3
                points = values[0].reshape(-1, 3)
            else:
                assert geometry.get("GeometryType") == "X_Y_Z" and len(values) == 3
                points = np.stack([v.reshape(-1) for v in values], axis=1)
                assert points.shape == (rows * cols, 3)
            for attribute in grid.findall("Attribute"):
                a = resolve(attribute.find("DataItem"), f)
                per_point = 3 if attribute.get("AttributeType") == "Vector" else 1
                assert a.size == rows * cols * per_point, (grid.get("Name"), attribute.get("Name"))
            if grid.get("Name").startswith("spherical/cube face "):
                face = int(grid.get("Name").split()[-1])
                # Face f is rows 3f .. 3f+2 of the (18, 3, 3) ramp: its first value is 27 f.
                assert points[0, 0] == 27 * face, (face, points[0])
            if grid.get("Name") == "batch/gim_4 b":
                # Item 1, plane y starts at flat position (1*3 + 1) * 16.
                assert points[0, 1] == 64 and points[0, 0] == 48 and points[0, 2] == 80, points[0]
            if grid.get("Name") == "batch/sphere_cube_1 c face 5":
                # Face 5 of plane x: rows 10, 11 of the (12, 2) plane 0, flat positions 20 .. 23.
                assert list(points[:, 0]) == [20, 21, 22, 23], points
        assert grid_count(root, "Temporal") == 2
    expected = ["gim/a", "spherical/cube face 0", "spherical/cube face 1", "spherical/cube face 2",
                "spherical/cube face 3", "spherical/cube face 4", "spherical/cube face 5", "spherical/oct",
                "batch/gim_4 a", "batch/gim_4 b"] + [f"batch/sphere_cube_1 c face {k}" for k in range(6)]
    assert names == expected, names
    print("xdmf sidecar ok:", len(names), "grids")


def grid_count(root, collection):
    return sum(1 for g in root.iter("Grid") if g.get("CollectionType") == collection)


if __name__ == "__main__":
    main()
