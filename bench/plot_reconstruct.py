#!/usr/bin/env python3
"""plot_reconstruct.py — the density-reconstruction plot from `ivr-bench --suite reconstruct`'s
results (its v*_to_*db cases; the earlier ivr_reconstruct_bench's JSON too):
held-out PSNR and relative volume error against wall time for each phantom size (default
settings: coarse to fine, Adam, 8 random views of 128² per iteration), the target PSNR dashed.

Usage: /usr/bin/python3 bench/plot_reconstruct.py RESULTS.json OUT.png
(Debian's python3-matplotlib, installed by scripts/install-deps.sh.)
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from plot_axes import number_log_axes  # noqa: E402


def main(path, out):
    with open(path) as f:
        doc = json.load(f)
    runs = doc["results"]
    device = doc.get("device", "")
    if doc.get("schema", "").startswith("ivr-bench/"):
        device = next((r["device"] for r in runs if r["suite"] == "reconstruct"), "")
        its = {r["params"]["volume"]: r["metrics"].get("iterations_per_s", float("nan"))
               for r in runs if r["suite"] == "reconstruct" and "_to_" not in r["case"]}
        runs = [{"n": r["params"]["volume"], "target_db": r["params"]["target_db"],
                 "views": r["params"]["views"], "batch": r["params"]["batch"],
                 "image": r["params"]["image"],
                 "iterations_per_second": its.get(r["params"]["volume"], float("nan")),
                 "curve": [[c["iteration"], c["seconds"], c["psnr_db"], c["volume_error"]]
                           for c in r.get("series", [])]}
                for r in runs if r["suite"] == "reconstruct" and "_to_" in r["case"]]
    if not runs:
        sys.exit("plot_reconstruct: the results hold no runs")
    fig, (psnr, error) = plt.subplots(1, 2, figsize=(10, 4))
    for run in runs:
        curve = run["curve"]  # [iteration, seconds, PSNR dB, volume error]
        secs = [c[1] for c in curve]
        label = f"{run['n']}³ ({run['iterations_per_second']:.2f} it/s)"
        psnr.plot(secs, [c[2] for c in curve], marker=".", label=label)
        error.plot(secs, [c[3] for c in curve], marker=".", label=label)
    target = runs[0]["target_db"]
    psnr.axhline(target, color="grey", linestyle="--", linewidth=1, label=f"target {target:g} dB")
    psnr.set_xlabel("seconds (evaluations excluded)")
    psnr.set_ylabel("held-out PSNR (dB)")
    error.set_xlabel("seconds (evaluations excluded)")
    error.set_ylabel("relative volume error ‖x − x_true‖ / ‖x_true‖")
    error.set_yscale("log")
    for ax in (psnr, error):
        ax.grid(True, alpha=0.3)
        ax.legend()
    fig.suptitle(f"Shepp–Logan density from {runs[0]['views']} views, batches of "
                 f"{runs[0]['batch']} × {runs[0]['image']}² — {device}", fontsize=9)
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
