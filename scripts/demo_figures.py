#!/usr/bin/env python3
"""demo_figures.py — the demo's pictures: target | before | after | error, and volume slices.

Writes PREFIX_compare.png: view 0 of the scene rendered at SIZE² (256 by default) from the true
volume (the target), from the starting volume (before) and from the reconstruction (after), with
the PSNR of each against the target, and the per-pixel |after − target| with a colour bar. And
PREFIX_slices.png: the central z, y and x slices of the truth, of the reconstruction and of their
difference, the first two on one shared colour scale.

Usage (scripts/demo.sh runs it):
  /usr/bin/python3 scripts/demo_figures.py --ivr build/ivr --scene SCENE.json --truth TRUTH.npy \\
      --result PREFIX_density.npy --start 0.5 -o out/reconstruct [--loss-csv PREFIX_loss.csv]
Needs numpy and matplotlib (Debian's python3-numpy and python3-matplotlib, installed by
scripts/install-deps.sh). The renders are ivr's own (`ivr render`), not resampled thumbnails: the
same camera as the reconstruction's view 0, at a size a person can see.
"""
import argparse
import copy
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


class FigureError(Exception):
    """A bad input, reported as one line."""


def psnr(image, reference):
    """PSNR in dB over every channel with peak 1, as ivr's psnr() computes it (inf if equal)."""
    mse = float(np.mean((image.astype(np.float64) - reference.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1 / mse)


def displayable(image):
    """(H, W, C) linear radiance as sRGB in [0, 1] for display, as ivr's PNG writer encodes it:
    RGB of a 4-channel image (its alpha is the opacity, not shown), grey for one channel."""
    rgb = image[..., :3] if image.shape[-1] >= 3 else np.repeat(image[..., :1], 3, axis=-1)
    v = np.clip(np.nan_to_num(rgb.astype(np.float64)), 0, 1)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


def db_text(value):
    return "∞" if math.isinf(value) else f"{value:.1f}"


def compare_figure(target, before, after, out, titles=None):
    """One PNG: target | before | after | |after − target| (mean over the colour channels) with
    its colour bar. Images (H, W, C) float. Returns each panel's (width, height) in pixels."""
    images = {"target": target, "before": before, "after": after}
    for name, image in images.items():
        if image.ndim != 3 or image.shape != target.shape:
            raise FigureError(f"the {name} image has shape {image.shape}; expected (H, W, C) "
                              f"like the target's {target.shape}")
        if not np.all(np.isfinite(image)):
            raise FigureError(f"the {name} image has a non-finite value")
    colour = slice(0, min(3, target.shape[-1]))
    error = np.mean(np.abs(after[..., colour].astype(np.float64) - target[..., colour]), axis=-1)
    titles = titles or {}
    h, w = target.shape[:2]
    # Each panel is drawn at one screen pixel per image pixel or more (never fewer than 256).
    scale = max(1.0, 256 / min(h, w))
    # The layout in inches at 100 dpi: panels side by side under two-line titles, then the bar
    # and its label.
    dpi = 100
    panel_w, panel_h = w * scale / dpi + 0.02, h * scale / dpi + 0.02
    margin, gap, top, bar, bar_label = 0.15, 0.15, 0.65, 0.18, 1.05
    fig_w = margin + 4 * panel_w + 4 * gap + bar + bar_label
    fig_h = margin + panel_h + top
    fig = plt.figure(figsize=(fig_w, fig_h), dpi=dpi)

    def place(x, width):  # an axes `width` inches wide at `x` inches, as tall as the panels
        return fig.add_axes([x / fig_w, margin / fig_h, width / fig_w, panel_h / fig_h])

    axes = [place(margin + k * (panel_w + gap), panel_w) for k in range(4)]
    cax = place(margin + 4 * panel_w + 3 * gap + gap / 2, bar)
    before_db, after_db = psnr(before, target), psnr(after, target)
    labels = [titles.get("target", "target"),
              titles.get("before", "before") + f"\nPSNR {db_text(before_db)} dB",
              titles.get("after", "after") + f"\nPSNR {db_text(after_db)} dB",
              f"|after − target|\nmax {np.max(error):.2g}"]
    for ax, image, label in zip(axes[:3], (target, before, after), labels):
        ax.imshow(displayable(image), interpolation="nearest")
    # The error's own scale from 0 to its maximum (a tiny floor so that a perfect match draws).
    shown = axes[3].imshow(error, cmap="magma", vmin=0, vmax=max(float(np.max(error)), 1e-12),
                           interpolation="nearest")
    for ax, label in zip(axes, labels):
        ax.set_title(label, fontsize=11)
        ax.set_xticks([])
        ax.set_yticks([])
    cb = fig.colorbar(shown, cax=cax)
    cb.set_label("|after − target|, mean of R, G, B\n(linear radiance, 1 = white)", fontsize=9)
    fig.savefig(out, dpi=dpi)
    fig.canvas.draw()
    sizes = [(ax.get_window_extent().width, ax.get_window_extent().height) for ax in axes]
    plt.close(fig)
    return sizes


def slices_figure(truth, result, out, title=""):
    """One PNG: rows truth, reconstruction, reconstruction − truth; columns the central z, y and x
    slices of the (nz, ny, nx) volumes. Truth and reconstruction share one colour scale."""
    if truth.ndim != 3 or result.shape != truth.shape:
        raise FigureError(f"the reconstruction has shape {result.shape} but the truth "
                          f"{truth.shape}; expected two (nz, ny, nx) volumes of one shape")
    for name, v in (("truth", truth), ("reconstruction", result)):
        if not np.all(np.isfinite(v)):
            raise FigureError(f"the {name} volume has a non-finite value")
    truth = truth.astype(np.float64)
    result = result.astype(np.float64)
    nz, ny, nx = truth.shape
    cuts = [(f"z = {nz // 2} (x–y plane)", lambda v: v[nz // 2, :, :], "x", "y"),
            (f"y = {ny // 2} (x–z plane)", lambda v: v[:, ny // 2, :], "x", "z"),
            (f"x = {nx // 2} (y–z plane)", lambda v: v[:, :, nx // 2], "y", "z")]
    lo = min(float(truth.min()), float(result.min()), 0.0)
    hi = max(float(truth.max()), float(result.max()), lo + 1e-12)
    diff = result - truth
    span = max(float(np.max(np.abs(diff))), 1e-12)
    fig, axes = plt.subplots(3, 3, figsize=(12.2, 11), dpi=100, constrained_layout=True)
    rows = (("truth", truth, "viridis", lo, hi), ("reconstruction", result, "viridis", lo, hi),
            ("reconstruction − truth", diff, "RdBu_r", -span, span))
    drawn = []
    for r, (name, volume, cmap, vmin, vmax) in enumerate(rows):
        for c, (cut_name, cut, xlabel, ylabel) in enumerate(cuts):
            ax = axes[r, c]
            image = ax.imshow(cut(volume), cmap=cmap, vmin=vmin, vmax=vmax, origin="lower",
                              interpolation="nearest")
            ax.set_title(f"{name}, {cut_name}", fontsize=10)
            ax.set_xlabel(f"{xlabel} (voxel)")
            ax.set_ylabel(f"{ylabel} (voxel)")
        drawn.append(image)
    fig.colorbar(drawn[0], ax=axes[:2, :].ravel().tolist(), shrink=0.9,
                 label="density (truth and reconstruction, one scale)")
    fig.colorbar(drawn[2], ax=axes[2, :].ravel().tolist(), shrink=0.9,
                 label="density difference")
    if title:
        fig.suptitle(title, fontsize=12)
    fig.savefig(out, dpi=100)
    plt.close(fig)


def relative_error(result, truth):
    """‖result − truth‖ / ‖truth‖, as ivr's relative_volume_error computes it."""
    norm = float(np.sqrt(np.sum(truth.astype(np.float64) ** 2)))
    diff = float(np.sqrt(np.sum((result.astype(np.float64) - truth) ** 2)))
    return diff / norm if norm > 0 else (math.inf if diff > 0 else 0.0)


def view_scene(scene, volume_path, size):
    """The scene's first camera alone (view 0 of an orbit), its longer side `size` pixels, over
    the volume in `volume_path`."""
    s = copy.deepcopy(scene)
    s["volume"] = {"file": os.path.abspath(volume_path)}
    cameras = s.get("cameras") or []
    if not cameras or not isinstance(cameras[0], dict):
        raise FigureError("the scene has no camera to render")
    camera = copy.deepcopy(cameras[0])
    lens = camera["orbit"] if "orbit" in camera else camera
    if "orbit" in camera:
        lens["views"] = 1  # view 0 of any orbit: its start angle
    w, h = int(lens.get("width", 64)), int(lens.get("height", 64))
    lens["width"], lens["height"] = ((size, max(1, round(size * h / w))) if w >= h
                                     else (max(1, round(size * w / h)), size))
    s["cameras"] = [camera]
    return s


def render(ivr, scene, volume_path, size, folder, name):
    """View 0 of `scene` over `volume_path` rendered by `ivr render`: (H, W, C) float."""
    path = os.path.join(folder, name + ".json")
    with open(path, "w") as f:
        json.dump(view_scene(scene, volume_path, size), f)
    out = os.path.join(folder, name + ".npy")
    run = subprocess.run([ivr, "render", path, "-o", out], capture_output=True, text=True)
    if run.returncode != 0:
        raise FigureError(f"ivr render failed: {run.stderr.strip() or run.stdout.strip()}")
    return np.load(out)[0]


def iterations_in(loss_csv):
    with open(loss_csv) as f:
        return sum(1 for _ in csv.DictReader(f))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--ivr", required=True, help="the ivr program")
    p.add_argument("--scene", required=True, help="the reconstruction's scene JSON")
    p.add_argument("--truth", required=True, help="the true volume, .npy (nz, ny, nx)")
    p.add_argument("--result", required=True, help="the reconstruction, PREFIX_density.npy")
    p.add_argument("--start", type=float, required=True, help="the constant starting density")
    p.add_argument("--loss-csv", help="PREFIX_loss.csv, for the iteration count in the titles")
    p.add_argument("--size", type=int, default=256, help="the renders' longer side in pixels")
    p.add_argument("-o", "--output", required=True, help="prefix: PREFIX_compare.png, "
                   "PREFIX_slices.png")
    a = p.parse_args(argv)
    try:
        if not (a.size >= 16):
            raise FigureError(f"--size must be >= 16, got {a.size}")
        if not (math.isfinite(a.start) and a.start >= 0):
            raise FigureError(f"--start must be a finite density >= 0, got {a.start}")
        with open(a.scene) as f:
            scene = json.load(f)
        truth, result = np.load(a.truth), np.load(a.result)
        if result.shape != truth.shape:
            raise FigureError(f"{a.result} has shape {result.shape} but {a.truth} "
                              f"{truth.shape}")
        after_title = "after"
        if a.loss_csv:
            after_title = f"after {iterations_in(a.loss_csv)} iterations"
        with tempfile.TemporaryDirectory() as tmp:
            start = os.path.join(tmp, "start.npy")
            np.save(start, np.full(truth.shape, a.start, dtype=np.float32))
            target = render(a.ivr, scene, a.truth, a.size, tmp, "target")
            before = render(a.ivr, scene, start, a.size, tmp, "before")
            after = render(a.ivr, scene, a.result, a.size, tmp, "after")
        compare = a.output + "_compare.png"
        compare_figure(target, before, after, compare,
                       {"target": "target: the truth, view 0",
                        "before": f"before: constant {a.start:g}", "after": after_title})
        slices = a.output + "_slices.png"
        slices_figure(truth, result, slices,
                      f"{'×'.join(str(n) for n in truth.shape[::-1])} volume: reconstruction "
                      f"against the truth (relative error "
                      f"{100 * relative_error(result, truth):.2f} %)")
    except (FigureError, OSError, ValueError, KeyError) as e:
        print(f"demo_figures: error: {e}", file=sys.stderr)
        return 1
    print(f"wrote {compare} and {slices}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
