#!/usr/bin/env python3
"""plot_tangents.py — the forward/adjoint crossover plot from `ivr-bench --suite planner`'s results
(its voxels_* cases; the earlier ivr_tangents_bench's JSON too).

Usage: /usr/bin/python3 bench/plot_tangents.py RESULTS.json [OUT.png]
(Debian's python3-matplotlib, installed by scripts/install-deps.sh.)
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from plot_axes import number_log_axes  # noqa: E402


def from_planner_suite(doc):
    """The planner suite's voxel sweep in the earlier program's form (kernel times in ms)."""
    recs = [r for r in doc["results"] if r["suite"] == "planner" and r["case"].startswith("voxels_")]
    kernel = lambda r: 1e3 * r["metrics"].get("device_median_s", r["metrics"].get("median_s", 0))
    adjoint = next(r for r in recs if r["implementation"] == "ivr-adjoint")
    rows = []
    for f in (r for r in recs if r["implementation"] == "ivr-forward"):
        a = next(r for r in recs if r["case"] == f["case"] and r["implementation"] == "ivr")
        rows.append({"parameters": f["params"]["parameters"], "forward_ms": kernel(f),
                     "adjoint_ms": kernel(adjoint), "auto_ms": kernel(a),
                     "auto_mode": "forward" if a["metrics"].get("auto_chose_forward") else "adjoint"})
    rows.sort(key=lambda r: r["parameters"])
    cross = next((r["parameters"] for r in rows if r["adjoint_ms"] < r["forward_ms"]), 0)
    return {"rows": rows, "render_ms": 1e3 * adjoint["metrics"]["render_s"],
            "volume": adjoint["params"]["volume"], "image": adjoint["params"]["image"],
            "device": adjoint["device"], "crossover_parameters": cross}


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    path = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) > 2 else path.rsplit(".", 1)[0] + ".png"
    with open(path) as f:
        doc = json.load(f)
    if doc.get("schema", "").startswith("ivr-bench/"):
        doc = from_planner_suite(doc)
    rows = doc["rows"]
    p = [r["parameters"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(p, [r["forward_ms"] for r in rows], "o-", label="forward (P lanes, passes of 32)")
    ax.plot(p, [r["adjoint_ms"] for r in rows], "s-", label="adjoint (every voxel)")
    for mode, marker in (("forward", "^"), ("adjoint", "v")):
        pts = [(r["parameters"], r["auto_ms"]) for r in rows if r["auto_mode"] == mode]
        if pts:
            ax.plot(*zip(*pts), marker, markersize=9, fillstyle="none",
                    label=f"--mode auto chose {mode}")
    ax.axhline(doc["render_ms"], color="grey", linestyle=":", label="render")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("parameters P")
    ax.set_ylabel("kernel time (ms, median)")
    cross = doc.get("crossover_parameters", 0)
    ax.set_title(f"{doc['volume']}³ volume, {doc['image']}² image — {doc['device']}\n"
                 f"adjoint faster from P = {cross}" if cross else "forward faster at every P")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
