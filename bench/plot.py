"""plot.py — draws ivr-bench results (ivr-bench/1 JSON) as PNG plots.

    python3 bench/plot.py RESULTS.json [-o OUTDIR] [--name PREFIX]

Writes PREFIX_speed_vs_error.png (integrators: time against error per scheme and step),
PREFIX_baselines.png (every implementation's median time per case, memory beside the gradient),
PREFIX_crossover.png (forward mode by lanes against the adjoint) and PREFIX_scaling.png (time and
memory as volume, image and 1/step grow, with the fitted exponents). A plot whose suite is not in
the file is skipped with a note.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from plot_axes import number_log_axes  # noqa: E402

COLOURS = {"ivr": "#1f77b4", "ivr-deterministic": "#6baed6", "ivr-resident": "#17becf",
           "ivr-resident-deterministic": "#9edae5", "native": "#2ca02c", "jax": "#d62728",
           "drjit": "#9467bd", "torch": "#ff7f0e"}
SCHEMES = {"midpoint": "#1f77b4", "trapezoid": "#2ca02c", "preintegrated": "#ff7f0e",
           "exact": "#d62728"}


def timed(results, suite):
    return [r for r in results if r["suite"] == suite and "median_s" in r["metrics"]]


def short(device: str) -> str:
    return device.split(" / ")[-1][:40]


def speed_vs_error(doc, path) -> bool:
    rows = [r for r in timed(doc["results"], "integrators") if "error_relative_l2" in r["metrics"]]
    if not rows:
        return False
    scenes = sorted({(r["params"]["volume"], r["params"]["look"]) for r in rows})
    cols = min(3, len(scenes))
    nrows = math.ceil(len(scenes) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(5 * cols, 4 * nrows), squeeze=False)
    for ax, (volume, look) in zip(axes.flat, scenes):
        lines = defaultdict(list)
        for r in rows:
            if (r["params"]["volume"], r["params"]["look"]) == (volume, look):
                lines[(short(r["device"]), r["params"]["scheme"])].append(
                    (r["metrics"]["median_s"], r["metrics"]["error_relative_l2"], r["params"]["step"]))
        for (device, scheme), pts in sorted(lines.items()):
            pts.sort()
            ax.plot([p[0] * 1e3 for p in pts], [max(p[1], 1e-12) for p in pts], "o-",
                    color=SCHEMES.get(scheme), label=f"{scheme}" + (f" ({device})" if len(doc["devices"]) > 1 else ""))
            for t, e, s in pts:
                if s:
                    ax.annotate(f"{s:g}", (t * 1e3, max(e, 1e-12)), fontsize=6, alpha=0.7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{volume}, {look}")
        ax.set_xlabel("median time (ms)")
        ax.set_ylabel("relative L2 error vs continuous")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(scenes):]:
        ax.axis("off")
    fig.suptitle("Speed against error (labels: step in voxels)")
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout(rect=(0, 0, 1, 0.97))  # room for the suptitle
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def baselines(doc, path, cases=None) -> bool:
    """One panel per case (`cases`: only those whose name is one of them), four to a row."""
    groups = defaultdict(dict)  # (suite, case) -> impl -> (median_s, memory)
    for r in doc["results"]:
        if r["suite"] not in ("render", "gradient", "planner", "crossover") or "median_s" not in r["metrics"]:
            continue
        if r["suite"] in ("crossover", "planner") and not r["case"].split("_")[-1].startswith("tf"):
            continue
        if cases and r["case"] not in cases:
            continue
        key = r["implementation"] if r["device"] == "host" else (
            r["implementation"] + ("" if len(doc["devices"]) == 1 else f" [{short(r['device'])}]"))
        groups[(r["suite"], r["case"])][key] = (r["metrics"]["median_s"], r["metrics"].get("memory_bytes"))
    if not groups:
        return False
    columns = min(4, len(groups))
    rows = (len(groups) + columns - 1) // columns
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 4.2 * rows), squeeze=False)
    for ax in axes.flat[len(groups):]:
        ax.set_visible(False)
    for ax, ((suite, case), impls) in zip(axes.flat, sorted(groups.items())):
        names = sorted(impls, key=lambda n: impls[n][0])
        times = [impls[n][0] for n in names]
        bars = ax.bar(range(len(names)), times,
                      color=[COLOURS.get(n.split(" ")[0], "#7f7f7f") for n in names])
        ax.set_yscale("log")
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
        ax.set_ylabel("median time (s)")
        ax.set_title(f"{suite}: {case}", fontsize=9)
        for b, n in zip(bars, names):
            mem = impls[n][1]
            label = f"{impls[n][0]:.3g}s"
            if suite == "gradient" and mem:
                label += f"\n{mem / 2**20:.0f} MiB"
            ax.annotate(label, (b.get_x() + b.get_width() / 2, b.get_height()), ha="center",
                        va="bottom", fontsize=7)
        ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.suptitle("ivr against the baselines (same scene, same step; lower is better)")
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def crossover(doc, path) -> bool:
    # The planner suite (called crossover before issue 20): its TF-lane sweep and adjoint, not its
    # voxel sweep (cases voxels_*).
    rows = [r for r in timed(doc["results"], "crossover") + timed(doc["results"], "planner")
            if not r["case"].startswith("voxels_")]
    if not rows:
        return False
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for device in sorted({r["device"] for r in rows}):
        fwd = sorted((r["params"]["lanes"], r["metrics"]["median_s"]) for r in rows
                     if r["device"] == device and r["implementation"] == "ivr-forward")
        adj = [r["metrics"]["median_s"] for r in rows
               if r["device"] == device and r["implementation"] == "ivr-adjoint"]
        if fwd:
            line, = ax.plot([p for p, _ in fwd], [t * 1e3 for _, t in fwd], "o-",
                            label=f"forward mode ({short(device)})")
            if adj:
                ax.axhline(adj[0] * 1e3, color=line.get_color(), ls="--",
                           label=f"adjoint, any P ({short(device)})")
        for r in doc["results"]:
            if r["suite"] in ("crossover", "planner") and r["device"] == device and \
                    r["case"].endswith("summary") and not r["case"].startswith("voxels_"):
                x = r["metrics"].get("crossover_lanes", -1)
                if x and x > 0:
                    ax.axvline(x, color="grey", ls=":", label=f"measured crossover {x:.1f} lanes")
                m = r["metrics"].get("model_crossover_lanes", -1)
                if m and m > 0:
                    ax.axvline(m, color="black", ls="-.", alpha=0.5,
                               label=f"cost model's crossover {m:g}")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("parameters P (tangent lanes)")
    ax.set_ylabel("median time (ms)")
    ax.set_title("Forward mode against the adjoint\n(TF and background parameters)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def scaling(doc, path) -> bool:
    rows = timed(doc["results"], "scaling")
    if not rows:
        return False
    exps = {}
    for r in doc["results"]:
        if r["suite"] == "scaling" and r["case"] == "exponents":
            exps[r["device"]] = r["metrics"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for ax, grows, xlabel in zip(axes, ("volume", "image", "step"),
                                 ("volume edge (voxels)", "image edge (pixels)", "1 / step (voxels⁻¹)")):
        per = "inverse_step" if grows == "step" else grows + "_edge"
        for device in sorted({r["device"] for r in rows}):
            for (op, marker), impl in ((o, i) for o in (("render", "o"), ("gradient", "s"))
                                       for i in ("ivr", "ivr-resident")):
                pts = sorted(((1 / r["params"]["step"]) if grows == "step" else r["params"][grows],
                              r["metrics"]["median_s"]) for r in rows
                             if r["device"] == device and r["params"]["grows"] == grows
                             and r["case"].endswith("_" + op) and r["implementation"] == impl)
                if not pts:
                    continue
                resident = impl == "ivr-resident"
                marker += ":" if resident else "-"
                k = None if resident else exps.get(device, {}).get(f"{op}_time_vs_{per}")
                label = f"{op}" + (" resident" if resident else "") + (
                    f", k = {k:.2f}" if k is not None and not math.isnan(k) else "")
                if len(exps) > 1:
                    label += f" ({short(device)})"
                ax.plot([p for p, _ in pts], [t for _, t in pts], marker, label=label)
            if grows == "volume":
                mem = sorted((r["params"]["volume"], r["metrics"].get("peak_device_bytes", 0) / 2**20)
                             for r in rows if r["device"] == device and r["params"]["grows"] == "volume"
                             and r["case"].endswith("_gradient") and r["implementation"] == "ivr")
                if mem:
                    ax2 = ax.twinx()
                    ax2.plot([p for p, _ in mem], [m for _, m in mem], "k:", alpha=0.6,
                             label="gradient device memory")
                    ax2.set_yscale("log")
                    ax2.set_ylabel("device memory (MiB)")
                    ax2.legend(fontsize=7, loc="lower right")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("median time (s)")
        ax.set_title(f"as the {grows} {'shrinks' if grows == 'step' else 'grows'}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Scaling (time ∝ x^k, least squares in log–log)")
    number_log_axes(fig)  # before the layout, which must fit the tick labels it adds
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def main() -> int:
    p = argparse.ArgumentParser(description="Draws ivr-bench results as PNG plots")
    p.add_argument("results", help="an ivr-bench/1 JSON file")
    p.add_argument("-o", "--outdir", default=".", help="folder for the PNGs")
    p.add_argument("--name", help="file name prefix (default: the results file's stem)")
    p.add_argument("--cases", help="comma-separated case names: the baselines plot shows only them")
    a = p.parse_args()
    cases = set(a.cases.split(",")) if a.cases else None
    try:
        with open(a.results) as f:
            doc = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        print(f"plot.py: cannot read {a.results}: {e}", file=sys.stderr)
        return 1
    if doc.get("schema") != "ivr-bench/1":
        print(f"plot.py: {a.results} is not an ivr-bench/1 results file", file=sys.stderr)
        return 1
    os.makedirs(a.outdir, exist_ok=True)
    name = a.name or os.path.splitext(os.path.basename(a.results))[0]
    for what, draw in (("speed_vs_error", speed_vs_error),
                       ("baselines", lambda d, path: baselines(d, path, cases)),
                       ("crossover", crossover), ("scaling", scaling)):
        path = os.path.join(a.outdir, f"{name}_{what}.png")
        if draw(doc, path):
            print(f"wrote {path}")
        else:
            print(f"plot.py: no {what} results in {a.results}; skipped", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
