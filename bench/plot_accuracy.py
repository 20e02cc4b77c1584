#!/usr/bin/env python3
"""plot_accuracy.py — the speed-against-error Pareto plots from ivr_accuracy_bench's JSON: one
panel per volume and look (transfer function and model), relative RMS error against time
(log-log), one curve per integrator (with and without empty-space skipping), the target error as
a dashed line. Writes one PNG per look: OUT_<look>.png.

Usage: /usr/bin/python3 bench/plot_accuracy.py RESULTS.json [OUT]
(Debian's python3-matplotlib, installed by scripts/install-deps.sh.)
"""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STYLES = {"midpoint": ("tab:blue", "o"), "trapezoid": ("tab:green", "s"),
          "preintegrated": ("tab:red", "^"), "exact": ("tab:purple", "D")}


def plot_look(doc, look, out):
    rows = [r for r in doc["rows"] if r["look"] == look]
    volumes = list(dict.fromkeys(r["volume"] for r in rows))
    integrators = list(dict.fromkeys(r["integrator"] for r in rows))
    target = doc["time_at_target"][0]["target_relative_rms"] if doc["time_at_target"] else None
    cols = min(4, len(volumes))
    nrows = math.ceil(len(volumes) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4 * cols, 3.4 * nrows), squeeze=False)
    for ax, volume in zip(axes.flat, volumes):
        for integ in integrators:
            pts = sorted((r for r in rows if r["volume"] == volume and r["integrator"] == integ),
                         key=lambda r: r["ms"])
            base = integ.split("+")[0]
            colour, marker = STYLES.get(base, ("black", "x"))
            ax.plot([r["ms"] for r in pts], [max(r["relative_rms"], 1e-9) for r in pts],
                    marker=marker, color=colour, ls="--" if "+skip" in integ else "-",
                    ms=4, lw=1, label=integ)
            if integ == "midpoint":
                for r in pts:
                    ax.annotate(f'{r["step"]:g}', (r["ms"], r["relative_rms"]), fontsize=6,
                                textcoords="offset points", xytext=(3, 3))
        if target:
            ax.axhline(target, ls=":", color="grey", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{volume} ({look})", fontsize=9)
        ax.set_xlabel("time (ms)")
        ax.set_ylabel("relative RMS error")
        ax.grid(True, which="both", lw=0.3)
    for ax in list(axes.flat)[len(volumes):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=6)
    fig.suptitle(f'speed against error on {doc["device"]} — look "{look}" ({doc["views"]} views '
                 f'of {doc["image"]}², reference: {doc["reference"]}; labels: midpoint steps)',
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(out)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    path = sys.argv[1]
    stem = sys.argv[2] if len(sys.argv) > 2 else path.rsplit(".", 1)[0]
    with open(path) as f:
        doc = json.load(f)
    for look in dict.fromkeys(r["look"] for r in doc["rows"]):
        plot_look(doc, look, f"{stem}_{look}.png")


if __name__ == "__main__":
    main()
