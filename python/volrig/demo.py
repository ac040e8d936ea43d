"""The README's demo: build the humanoid phantom, skeletonize it, write pictures and a report."""
from __future__ import annotations

import json
import os
import platform
import time

import numpy as np


def skeleton_figure(path: str, volume, mask, skeleton, thinness: float, recon, counts, title: str,
                    thin: float = 0.8) -> None:
    """Projections of the volume with the skeleton at ``thinness`` (front and side) and at a thinner ``thin``
    (colour and size = sphere radius), the reconstruction with its missing voxels in red, and the point count
    against thinness."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .files import atomic_output

    a = volume.array.astype(np.float32)
    sx, sy, sz = volume.spacing
    nz, ny, nx = a.shape
    wide, deep = nx * sx, ny * sy
    fig, axes = plt.subplots(1, 5, figsize=(19, 8.5),
                             gridspec_kw={"width_ratios": [wide, deep, wide, wide, 1.3 * wide]})
    views = ((axes[0], thinness, 1, 0, "front"), (axes[1], thinness, 2, 1, "side"), (axes[2], thin, 1, 0, "front"))
    points = {tp: skeleton.at(tp) for tp in (thinness, thin)}
    rmax = float(points[thinness].radii.max())
    for ax, tp, axis, u, label in views:
        pts = points[tp]
        c, r = pts.centers, pts.radii
        order = np.argsort(r)
        proj = a.max(axis=axis)
        ext = (volume.origin[u], volume.origin[u] + proj.shape[1] * volume.spacing[u],
               volume.origin[2], volume.origin[2] + nz * sz)
        ax.imshow(proj, cmap="gray", origin="lower", extent=ext, alpha=0.4)
        sc = ax.scatter(c[order, u], c[order, 2], c=r[order], s=0.3 + 12.0 * r[order] / rmax, cmap="viridis",
                        vmin=0, vmax=rmax, linewidths=0)
        ax.set_title(f"{label}, TP {tp}\n{len(pts):,} points", fontsize=11)
        ax.set_aspect("equal")
        ax.axis("off")
    fig.colorbar(sc, ax=axes[:3], shrink=0.35, label="sphere radius (world units)", location="bottom", pad=0.02)
    missing = mask & ~recon
    ext = (volume.origin[0], volume.origin[0] + nx * sx, volume.origin[2], volume.origin[2] + nz * sz)
    axes[3].imshow(recon.max(axis=1), cmap="Blues", origin="lower", extent=ext, vmin=0, vmax=1.6)
    mz, my, mx = np.nonzero(missing)
    axes[3].scatter(volume.origin[0] + mx * sx, volume.origin[2] + mz * sz, s=1, c="red", linewidths=0)
    axes[3].set_title(f"reconstruction, TP {thinness}\n{missing.sum():,} voxels missing (red)", fontsize=11)
    axes[3].set_aspect("equal")
    axes[3].axis("off")
    tps, ns = zip(*counts)
    axes[4].semilogy(tps, ns, "o-")
    for tp in (thinness, thin):
        axes[4].axvline(tp, color="gray", ls="--")
    axes[4].set_xlabel("thinness TP")
    axes[4].set_ylabel("skeleton points")
    axes[4].set_title("points vs thinness", fontsize=11)
    axes[4].set_box_aspect(1.4)
    fig.suptitle(title, fontsize=13)
    with atomic_output(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=80, bbox_inches="tight", format="png")
    plt.close(fig)


def run_demo(out_dir: str = "out/demo", scale: float = 0.5, thinness: float = 0.3) -> dict:
    """Phantom -> mask -> skeleton -> reconstruction; writes skeleton.png, report.json and report.md to
    ``out_dir``; returns the report."""
    from . import phantom, reconstruct, reconstruction_loss
    from .files import atomic_output
    from .pipeline import Segmentation, skeleton_of, skeleton_points

    os.makedirs(out_dir, exist_ok=True)
    t0 = time.perf_counter()
    ph = phantom.humanoid(scale=scale)
    t_phantom = time.perf_counter() - t0
    mask = Segmentation().mask(ph.volume, name="the phantom")
    t0 = time.perf_counter()
    sk = skeleton_of(mask)
    t_skel = time.perf_counter() - t0
    t0 = time.perf_counter()
    pts = skeleton_points(sk, thinness=thinness)
    t_at = time.perf_counter() - t0
    recon = reconstruct(pts, mask)
    loss = reconstruction_loss(recon, mask)
    counts = [(tp, max(sk.count(tp), 1)) for tp in np.round(np.arange(0.0, 1.45, 0.1), 2)]
    x, y, z = ph.volume.dims
    report = {
        "phantom": {"scale": scale, "dims_xyz": [x, y, z], "object_voxels": sk.object_count,
                    "build_seconds": round(t_phantom, 3)},
        "skeleton": {"metric": sk.metric, "thinness": thinness, "points": len(pts),
                     "percent_of_object": round(100.0 * len(pts) / sk.object_count, 3),
                     "skeletonize_seconds": round(t_skel, 3), "rethreshold_ms": round(1000 * t_at, 3)},
        "reconstruction": {"lost_voxels": loss, "percent_lost": round(100.0 * loss / sk.object_count, 4)},
        "points_by_thinness": {str(tp): n for tp, n in counts},
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
    }
    skeleton_figure(os.path.join(out_dir, "skeleton.png"), ph.volume, mask.array, sk, thinness, recon.array, counts,
                    f"volrig: humanoid phantom {x} x {y} x {z}, Euclidean thinness skeletons")
    with atomic_output(os.path.join(out_dir, "report.json")) as tmp:
        with open(tmp, "w") as f:
            json.dump(report, f, indent=2)
    md = (f"# volrig demo report\n\n"
          f"- phantom: {x} x {y} x {z} voxels (scale {scale}), {sk.object_count:,} object voxels, "
          f"built in {t_phantom:.2f} s\n"
          f"- skeletonize (Euclidean DT + scores + sorted order): {t_skel:.3f} s\n"
          f"- skeleton at thinness {thinness}: {len(pts):,} points = "
          f"{report['skeleton']['percent_of_object']}% of the object, re-thresholded in {1000 * t_at:.2f} ms\n"
          f"- reconstruction from those spheres: {loss:,} voxels lost "
          f"({report['reconstruction']['percent_lost']}%)\n\n![skeleton](skeleton.png)\n\n"
          "| thinness | points |\n|---:|---:|\n" + "".join(f"| {tp} | {n:,} |\n" for tp, n in counts))
    with atomic_output(os.path.join(out_dir, "report.md")) as tmp:
        with open(tmp, "w") as f:
            f.write(md)
    print(md.split("\n\n![")[0])
    print(f"\nwrote {out_dir}/skeleton.png, report.md, report.json")
    return report
