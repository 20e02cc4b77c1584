#!/usr/bin/env python3
"""plot_accuracy.py — the speed-against-error Pareto plot from ivr_accuracy_bench's JSON: one
panel per scene, relative RMS error against time (log-log), one curve per integrator (points
labelled with their step), the target error as a dashed line.

Usage: /usr/bin/python3 bench/plot_accuracy.py RESULTS.json [OUT.png]
(Debian's python3-matplotlib, installed by scripts/install-deps.sh.)
"""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    path = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) > 2 else path.rsplit(".", 1)[0] + ".png"
    with open(path) as f:
        doc = json.load(f)
    rows = doc["rows"]
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    integrators = list(dict.fromkeys(r["integrator"] for r in rows))
    target = doc["time_at_target"][0]["target_relative_rms"] if doc["time_at_target"] else None
    cols = min(4, len(scenes))
    nrows = math.ceil(len(scenes) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4 * cols, 3.4 * nrows), squeeze=False)
    for ax, scene in zip(axes.flat, scenes):
        for k, integ in enumerate(integrators):
            pts = [r for r in rows if r["scene"] == scene and r["integrator"] == integ]
            ax.plot([r["ms"] for r in pts], [r["relative_rms"] for r in pts],
                    ("o-", "s--", "^-.", "v:")[k % 4], label=integ)
            if k == 0:
                for r in pts:
                    ax.annotate(f'{r["step"]:g}', (r["ms"], r["relative_rms"]), fontsize=7,
                                textcoords="offset points", xytext=(3, 3))
        if target:
            ax.axhline(target, ls="--", color="grey", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(scene)
        ax.set_xlabel("time (ms)")
        ax.set_ylabel("relative RMS error")
        ax.grid(True, which="both", lw=0.3)
    for ax in list(axes.flat)[len(scenes):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(f'speed against error on {doc["device"]} ({doc["views"]} views of '
                 f'{doc["image"]}², reference: {doc["reference"]["precision"]} at step '
                 f'{doc["reference"]["step"]:g}; labels: step in voxels)', fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
