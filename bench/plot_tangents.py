#!/usr/bin/env python3
"""plot_tangents.py — the forward/adjoint crossover plot from ivr_tangents_bench's JSON.

Usage: /usr/bin/python3 bench/plot_tangents.py RESULTS.json [OUT.png]
(Debian's python3-matplotlib, installed by scripts/install-deps.sh.)
"""
import json
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
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
