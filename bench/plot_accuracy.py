#!/usr/bin/env python3
"""plot_accuracy.py — the speed-against-error Pareto plots from `ivr-bench --suite integrators`
(or the earlier ivr_accuracy_bench's JSON): one panel per volume and look (transfer function and
model), relative RMS error against time (log-log), one curve per integrator (with and without
empty-space skipping), the target error as a dashed line. Writes one PNG per look:
OUT_<look>.png.

Usage: /usr/bin/python3 bench/plot_accuracy.py RESULTS.json [OUT] [--device SUBSTRING]
(the first device with integrators records unless --device names another; Debian's
python3-matplotlib, installed by scripts/install-deps.sh.)
"""
import argparse
import json
import math
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from accuracy_records import accuracy_doc  # noqa: E402
from plot_axes import number_log_axes  # noqa: E402

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
            ax.axhline(target, ls=":", color="grey", lw=0.8, label=f"target error {target:g}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{volume} ({look})", fontsize=9)
        ax.set_xlabel("time (ms)")
        ax.set_ylabel("relative RMS error")
        ax.grid(True, which="both", lw=0.3)
    for ax in list(axes.flat)[len(volumes):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=6)
    title = (f'speed against error on {doc["device"]} — look "{look}" ({doc["views"]} views of '
             f'{doc["image"]}², reference: {doc["reference"]}; time: median kernel (+ grid); '
             'labels: midpoint steps)')
    fig.suptitle(textwrap.fill(title, 45 * cols), fontsize=9)
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(out)


def main():
    parser = argparse.ArgumentParser(description="speed-against-error Pareto plots")
    parser.add_argument("results")
    parser.add_argument("out", nargs="?", help="file stem (default: RESULTS without .json)")
    parser.add_argument("--device", help="a substring of the device's name")
    args = parser.parse_args()
    stem = args.out or args.results.rsplit(".", 1)[0]
    with open(args.results) as f:
        doc = accuracy_doc(json.load(f), args.device)
    if not doc["rows"]:
        raise SystemExit(f"{args.results}: no timed speed-against-error points")
    for look in dict.fromkeys(r["look"] for r in doc["rows"]):
        plot_look(doc, look, f"{stem}_{look}.png")


if __name__ == "__main__":
    main()
