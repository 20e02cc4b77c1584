#!/usr/bin/env python3
"""plot_tomo.py — the convergence plot from `ivr-bench --suite tomo`'s results (its convergence_*
cases; the earlier ivr_tomo_bench's JSON too): relative residual
‖p − N x‖/‖p‖ of CGLS, LSQR and SIRT on the 64³ Shepp–Logan from 90 parallel views, against the
iteration and against wall time (log scale), with each solver's final volume error in the legend.

Usage: /usr/bin/python3 bench/plot_tomo.py RESULTS.json OUT.png
(Debian's python3-matplotlib, installed by scripts/install-deps.sh.)
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from plot_axes import number_log_axes  # noqa: E402

STYLES = {"cgls": "tab:blue", "lsqr": "tab:orange", "sirt": "tab:green"}


def main(path, out):
    with open(path) as f:
        doc = json.load(f)
    device = doc.get("device", "")
    if "results" in doc:  # ivr-bench: the tomo suite's convergence cases
        runs = [{"solver": r["params"]["solver"], "volume": r["params"]["volume"],
                 "views": r["params"]["views"], "history": r.get("series", []),
                 "volume_error": r["metrics"].get("volume_error", float("nan"))}
                for r in doc["results"]
                if r["suite"] == "tomo" and r["case"].startswith("convergence_")]
        device = next((r["device"] for r in doc["results"] if r["suite"] == "tomo"), "")
    else:
        runs = doc["convergence"]
    if not runs:
        sys.exit("plot_tomo: the results hold no convergence histories")
    fig, (by_iter, by_time) = plt.subplots(1, 2, figsize=(10, 4))
    for run in runs:
        its = [h["iteration"] for h in run["history"]]
        res = [h["residual"] for h in run["history"]]
        secs = [h["seconds"] for h in run["history"]]
        label = f'{run["solver"].upper()} (volume error {100 * run["volume_error"]:.1f} %)'
        colour = STYLES.get(run["solver"], None)
        by_iter.semilogy(its, res, label=label, color=colour)
        by_time.semilogy(secs, res, label=label, color=colour)
    n, views = runs[0]["volume"], runs[0]["views"]
    for ax, xlabel in ((by_iter, "iteration"), (by_time, "wall time (s)")):
        ax.axhline(0.01, color="grey", linestyle="--", linewidth=0.8, label="1 % residual")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relative residual ‖p − N x‖ / ‖p‖")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"{n}³ Shepp–Logan, {views} parallel views — {device}")
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
