#!/usr/bin/env python3
"""Rate-distortion curves of the image codecs against Draco (issue #19, docs/compression.md).

For one mesh: converts it once per representation (geometry image at each --sizes, spherical images of each
--domains at n = (size - 1) / 2), then for every byte budget and codec runs
    gimforge compress BASE.h5 --name KIND/NAME --codec C --bytes B -o tmp.h5 --json --no-metric
    gimforge reconstruct tmp.h5 -o tmp.ply
    gimforge metrics MESH tmp.ply --json            (symmetric RMS Hausdorff PSNR against the input)
and for every Draco quantization `draco_encoder -i MESH -o d.drc -qp Q -cl 10`, `draco_decoder`, metrics.
Bytes: the item's stored bytes (every dataset, attribute and name, as compress counts them) and the .drc file.
Writes OUT/rd_<mesh>.csv and, when matplotlib is installed (python3-matplotlib), OUT/rd_<mesh>.png.

    bench/rd_curves.py ../shared/data/meshes/bunny_closed.ply --out bench/out/rd
"""
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_GIMFORGE = os.path.join(HERE, "..", "build", "gimforge")


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    return r.stdout


def psnr(gimforge, mesh, other, samples):
    out = run([gimforge, "-q", "metrics", mesh, other, "--json", "-n", str(samples)])
    return json.loads(out)["psnr"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("--out", default=os.path.join(HERE, "out", "rd"))
    ap.add_argument("--gimforge", default=DEFAULT_GIMFORGE)
    ap.add_argument("--sizes", type=int, nargs="+", default=[257, 513])
    ap.add_argument("--domains", nargs="+", default=["flat-octa", "octa"])
    ap.add_argument("--bytes", type=int, nargs="+", default=[2000, 3000, 4000, 6000, 8000, 12000, 16000, 24000, 32000])
    ap.add_argument("--codecs", nargs="+", default=["j2k", "wavelet"])
    ap.add_argument("--draco-qp", type=int, nargs="+", default=list(range(6, 17, 2)))
    ap.add_argument("--samples", type=int, default=1000000, help="metric samples per direction")
    ap.add_argument("--keep", action="store_true", help="keep the converted archives in OUT")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    stem = os.path.splitext(os.path.basename(a.mesh))[0]
    work = tempfile.mkdtemp(prefix="rd_", dir=a.out)
    rows = []
    try:
        reps = []
        for size in a.sizes:
            base = os.path.join(work, f"gim{size}.h5")
            run([a.gimforge, "-q", "convert", a.mesh, "--method", "gim", "--size", str(size), "--name", stem, "-o", base])
            reps.append((f"gim{size}", base, f"gim/{stem}"))
            for domain in a.domains:
                base = os.path.join(work, f"{domain}{size}.h5")
                run([a.gimforge, "-q", "convert", a.mesh, "--method", "sphere", "--domain", domain, "--n", str((size - 1) // 2),
                     "--name", stem, "-o", base])
                reps.append((f"{domain}{size}", base, f"spherical/{stem}"))
        for rep, base, item in reps:
            ply = os.path.join(work, "full.ply")
            run([a.gimforge, "reconstruct", base, "--name", item, "-o", ply])
            rows.append({"mesh": stem, "representation": rep, "codec": "float32", "target": "",
                         "bytes": os.path.getsize(base),  # the whole archive of the one float32 item
                         "psnr": psnr(a.gimforge, a.mesh, ply, a.samples)})
            print(f"{rep:>14} float32 {rows[-1]['bytes']:>9} bytes {rows[-1]['psnr']:.2f} dB", flush=True)
            for codec in a.codecs:
                for b in a.bytes:
                    coded = os.path.join(work, "coded.h5")
                    if os.path.exists(coded):
                        os.remove(coded)
                    try:
                        out = json.loads(run([a.gimforge, "-q", "compress", base, "--name", item, "--codec", codec, "--bytes",
                                              str(b), "--no-metric", "--json", "-o", coded]))
                    except RuntimeError as e:
                        print(f"{rep:>14} {codec:>8} {b:>9}: {e}", file=sys.stderr)
                        continue
                    it = out["items"][0]
                    run([a.gimforge, "reconstruct", coded, "--name", item, "-o", ply])
                    p = psnr(a.gimforge, a.mesh, ply, a.samples)
                    rows.append({"mesh": stem, "representation": rep, "codec": codec, "target": b, "bytes": it["bytes"],
                                 "psnr": p, "seam_gap": it.get("seam_gap", 0.0)})
                    print(f"{rep:>14} {codec:>8} {it['bytes']:>9} bytes {p:.2f} dB", flush=True)
        for q in a.draco_qp:
            drc, ply = os.path.join(work, "d.drc"), os.path.join(work, "d.ply")
            run(["draco_encoder", "-i", a.mesh, "-o", drc, "-qp", str(q), "-cl", "10"])
            run(["draco_decoder", "-i", drc, "-o", ply])
            rows.append({"mesh": stem, "representation": "mesh", "codec": f"draco", "target": q,
                         "bytes": os.path.getsize(drc), "psnr": psnr(a.gimforge, a.mesh, ply, a.samples)})
            print(f"{'mesh':>14} draco qp {q:>2} {rows[-1]['bytes']:>9} bytes {rows[-1]['psnr']:.2f} dB", flush=True)
    finally:
        if a.keep:
            print(f"archives kept in {work}")
        else:
            shutil.rmtree(work, ignore_errors=True)
    path = os.path.join(a.out, f"rd_{stem}.csv")
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["mesh", "representation", "codec", "target", "bytes", "psnr", "seam_gap"])
        w.writeheader()
        for r in rows:
            w.writerow(r)
    print(f"wrote {path}")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed (apt-get install python3-matplotlib): no plot", file=sys.stderr)
        return
    fig, ax = plt.subplots(figsize=(8, 5.5))
    series = {}
    for r in rows:
        if r["codec"] == "float32":
            continue
        series.setdefault((r["representation"], r["codec"]), []).append((r["bytes"], r["psnr"]))
    for (rep, codec), pts in sorted(series.items()):
        pts.sort()
        style = "k-o" if codec == "draco" else ("-s" if codec == "wavelet" else "--^")
        ax.plot([p[0] / 1000 for p in pts], [p[1] for p in pts], style, markersize=3,
                label="Draco (qp 6..16)" if codec == "draco" else f"{rep} {codec}")
    ax.axvline(16, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("stored bytes (KB)")
    ax.set_ylabel("PSNR (dB), symmetric RMS Hausdorff vs input")
    ax.set_title(f"{stem}: rate-distortion")
    ax.set_xscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    png = os.path.join(a.out, f"rd_{stem}.png")
    fig.savefig(png, dpi=110, bbox_inches="tight")
    print(f"wrote {png}")


if __name__ == "__main__":
    main()
