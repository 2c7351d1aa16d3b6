#!/usr/bin/env python3
"""Split a gimforge batch job into slices for a Slurm array job (slurm/convert_array.sbatch).

    slurm/split_collection.py JOB.toml N SLICES_DIR

JOB.toml is a `gimforge batch --job` file (docs/cli.md: [[collection]] tables with `input` or `list`,
`label`, `prefix`; [[output]] tables; `metric_samples`). The script finds the collection's meshes the way
gimforge does and deals them into N slices of about equal total file size (largest first, each to the
lightest slice). Slice k becomes the job file SLICES_DIR/kkkk.toml (0000.toml, 0001.toml, ...): the same
outputs and metric_samples, and the slice's meshes as list collections (SLICES_DIR/kkkk/*.txt, absolute
paths) whose prefixes and label rules give every mesh the item name and label it has in the whole job
(e.g. `chair/0001`, label `chair`). SLICES_DIR/manifest.tsv lists "slice<TAB>item name<TAB>path".

Fewer slices than N are made when the job has fewer meshes. SLICES_DIR must not exist or be empty.
The last line printed is the sbatch command to submit (array indices 0 .. slices - 1).
Needs Python >= 3.11 (tomllib; Debian 12's python3). Exit status: 0 done, 1 error, 2 usage error.
"""
import heapq
import json
import os
import sys
import tomllib

MESH_EXTENSIONS = {".ply", ".obj", ".off", ".stl"}


class JobError(Exception):
    pass


def _raise(error):
    raise error


def _is_mesh(name):
    return os.path.splitext(name)[1].lower() in MESH_EXTENSIONS


def from_directory(root, prefix, label):
    """Items of an `input` collection: (name, path, list prefix, list label), as gimforge names them."""
    if not os.path.isdir(root):
        raise JobError(f"{root}: not a directory (input)")
    items = []
    for folder, dirs, files in os.walk(root, onerror=_raise):  # like gimforge: symlinked folders not entered
        dirs.sort()
        for f in sorted(files):
            path = os.path.join(folder, f)
            if not (_is_mesh(f) and os.path.isfile(path)):
                continue
            rel = os.path.relpath(path, root)
            rel_folder = os.path.dirname(rel)
            # As a list item the name is prefix + stem: the folder goes into the prefix. The list's
            # "folder" label is the parent folder's name, which is the directory input's label too, except
            # for files directly in root (label "" there).
            list_prefix = prefix + (rel_folder.replace(os.sep, "/") + "/" if rel_folder else "")
            list_label = "none" if label == "folder" and not rel_folder else label
            items.append((prefix + os.path.splitext(rel)[0].replace(os.sep, "/"), path, list_prefix, list_label))
    return items


def from_list(list_path, prefix, label):
    """Items of a `list` collection, read like gimforge reads list files."""
    try:
        with open(list_path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise JobError(f"{list_path}: cannot open the list file ({e.strerror})") from e
    items = []
    for line in lines:
        line = line.rstrip(" \t\r").lstrip(" \t")
        if not line or line.startswith("#"):
            continue
        path = os.path.normpath(os.path.join(os.path.dirname(list_path), line))
        items.append((prefix + os.path.splitext(os.path.basename(path))[0], path, prefix, label))
    return items


def read_job(job_path):
    """(items, top-level lines, [[output]] lines) of a job file; items as (name, path, list prefix, label)."""
    try:
        with open(job_path, "rb") as f:
            job = tomllib.load(f)
    except OSError as e:
        raise JobError(f"{job_path}: cannot read the job file ({e.strerror})") from e
    except tomllib.TOMLDecodeError as e:
        raise JobError(f"{job_path}: {e}") from e
    unknown = set(job) - {"metric_samples", "collection", "output"}
    if unknown:
        raise JobError(f"{job_path}: unknown key(s) {', '.join(sorted(unknown))}")
    if not job.get("collection") or not job.get("output"):
        raise JobError(f"{job_path}: needs [[collection]] and [[output]] tables")
    base = os.path.dirname(os.path.abspath(job_path))
    items = []
    for c in job["collection"]:
        if ("input" in c) == ("list" in c):
            raise JobError(f"{job_path}: a [[collection]] needs exactly one of 'input' and 'list'")
        prefix, label = c.get("prefix", ""), c.get("label", "folder")
        if "input" in c:
            items += from_directory(os.path.join(base, c["input"]), prefix, label)
        else:
            items += from_list(os.path.join(base, c["list"]), prefix, label)
    if not items:
        raise JobError(f"{job_path}: the collection has no meshes (.ply .obj .off .stl)")
    seen = {}
    for name, path, _, _ in items:
        if name in seen:
            raise JobError(f"two meshes would get the item name '{name}': {seen[name]} and {path}")
        if path != path.strip() or "\n" in path or "\r" in path:
            raise JobError(f"{path!r}: a path with surrounding blanks or line breaks cannot go in a list file")
        seen[name] = path
    header = [f"metric_samples = {_toml_value(job['metric_samples'])}"] if "metric_samples" in job else []
    outputs = []
    for o in job["output"]:
        outputs.append("[[output]]")
        outputs += [f"{k} = {_toml_value(v)}" for k, v in o.items()]
    return items, header, outputs


def _toml_value(v):
    if isinstance(v, (bool, int, float, str)):
        return json.dumps(v, ensure_ascii=False)  # a JSON string or number is a TOML basic string / number
    raise JobError(f"unsupported value {v!r} in the job file")


def split(items, n):
    """Slices of about equal total file size: longest first, each to the lightest slice."""
    sized = [(os.path.getsize(item[1]), item) for item in items]
    count = min(n, len(items))
    heap = [(0, k) for k in range(count)]
    slices = [[] for _ in range(count)]
    for size, item in sorted(sized, key=lambda s: (-s[0], s[1][0])):
        load, k = heapq.heappop(heap)
        slices[k].append(item)
        heapq.heappush(heap, (load + max(size, 1), k))
    return [sorted(s) for s in slices]


def write_slices(slices, header, outputs, slices_dir):
    os.makedirs(slices_dir, exist_ok=True)
    with open(os.path.join(slices_dir, "manifest.tsv"), "w", encoding="utf-8") as manifest:
        for k, items in enumerate(slices):
            tag = f"{k:04d}"
            groups = {}
            for name, path, prefix, label in items:
                groups.setdefault((prefix, label), []).append(path)
                manifest.write(f"{k}\t{name}\t{path}\n")
            os.makedirs(os.path.join(slices_dir, tag), exist_ok=True)
            job = [f"# slice {k} of {len(slices)}: {len(items)} meshes (slurm/split_collection.py)"] + header
            for g, ((prefix, label), paths) in enumerate(sorted(groups.items())):
                list_path = os.path.join(tag, f"{g:05d}.txt")  # relative to the job file's folder
                with open(os.path.join(slices_dir, list_path), "w", encoding="utf-8") as f:
                    f.writelines(os.path.abspath(p) + "\n" for p in sorted(paths))
                job += ["[[collection]]", f"list = {_toml_value(list_path)}", f"label = {_toml_value(label)}",
                        f"prefix = {_toml_value(prefix)}"]
            with open(os.path.join(slices_dir, tag + ".toml"), "w", encoding="utf-8") as f:
                f.write("\n".join(job + outputs) + "\n")


def main(argv):
    if len(argv) == 2 and argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0
    if len(argv) != 4:
        print("usage: split_collection.py JOB.toml N SLICES_DIR   (--help for more)", file=sys.stderr)
        return 2
    job_path, slices_dir = argv[1], argv[3]
    try:
        n = int(argv[2])
        if n < 1:
            raise ValueError
    except ValueError:
        print(f"split_collection: N must be a positive integer, not '{argv[2]}'", file=sys.stderr)
        return 2
    try:
        if os.path.exists(slices_dir) and (not os.path.isdir(slices_dir) or os.listdir(slices_dir)):
            raise JobError(f"{slices_dir}: exists and is not an empty folder")
        items, header, outputs = read_job(job_path)
        slices = split(items, n)
        write_slices(slices, header, outputs, slices_dir)
    except (JobError, OSError) as e:
        print(f"split_collection: error: {e}", file=sys.stderr)
        return 1
    sizes = [len(s) for s in slices]
    print(f"{len(items)} meshes in {len(slices)} slices of {min(sizes)} to {max(sizes)} meshes: "
          f"{os.path.join(slices_dir, '0000.toml')} ...")
    print(f"sbatch --array=0-{len(slices) - 1} slurm/convert_array.sbatch {slices_dir} OUT_DIR")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
