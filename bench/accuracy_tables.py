#!/usr/bin/env python3
"""accuracy_tables.py — docs/performance.md's tables from `ivr-bench --suite integrators` (the
time at the target error per look, volume and integrator with the best against midpoint; the exact
scheme's error in both precisions; the tolerance section's worst cases) and from `ivr-bench
--suite stability` (per hard case and integrator: forward error, float32-vs-float64 gradient
error, non-finite values); the earlier accuracy and stability programs' JSON too.
Prints Markdown.

Usage: /usr/bin/python3 bench/accuracy_tables.py RESULTS.json [--device SUBSTRING]
(the first device with integrators records unless --device names another)
"""
import argparse
import json

from accuracy_records import accuracy_doc, devices


def fmt(v, spec=".1f"):
    return "—" if v is None else format(v, spec)


def time_tables(doc):
    target = doc["time_at_target"][0]["target_relative_rms"]
    looks = list(dict.fromkeys(r["look"] for r in doc["time_at_target"]))
    for look in looks:
        rows = [r for r in doc["time_at_target"] if r["look"] == look]
        integrators = list(dict.fromkeys(r["integrator"] for r in rows))
        print(f"\nLook `{look}`: ms to reach a relative RMS error of {target:g} "
              "(— : not reached at the smallest step)\n")
        print("| volume | " + " | ".join(integrators) + " | best | best / midpoint |")
        print("|---" * (len(integrators) + 3) + "|")
        for volume in dict.fromkeys(r["volume"] for r in rows):
            ms = {r["integrator"]: r["ms_at_target"] for r in rows if r["volume"] == volume}
            best = next(b for b in doc["best_against_midpoint"]
                        if b["volume"] == volume and b["look"] == look)
            speed = best["speedup"]
            print(f"| {volume} | " + " | ".join(fmt(ms[i]) for i in integrators) +
                  f" | {best['best'] or '—'} | {fmt(speed, '.2f')} |")


def exact_table(doc):
    if not doc["exact"]:
        return
    print("\nThe exact scheme (absorption look): error against the continuous integral, worst over "
          "every step setting\n")
    print("| volume | f32 relative RMS | f32 relative max | f64 relative RMS | f64 relative max |")
    print("|---|---|---|---|---|")
    for volume in dict.fromkeys(r["volume"] for r in doc["exact"]):
        rs = [r for r in doc["exact"] if r["volume"] == volume]
        worst = {(p, m): max(r[p][m] for r in rs) for p in ("f32", "f64")
                 for m in ("relative_rms", "relative_max")}
        print(f"| {volume} | {worst['f32', 'relative_rms']:.1e} | {worst['f32', 'relative_max']:.1e}"
              f" | {worst['f64', 'relative_rms']:.1e} | {worst['f64', 'relative_max']:.1e} |")


def tolerance_table(doc):
    rows = doc["tolerance"]
    if not rows:
        return
    print("\nTolerance: per look, scheme and tolerance, over every volume: the worst measured "
          "error / tolerance, and the range of needed step / chosen step\n")
    print("| look | scheme | tolerance | cases | below | worst error / tolerance | "
          "needed / chosen | pilots | choose s (max) |")
    print("|---|---|---|---|---|---|---|---|---|")
    keys = list(dict.fromkeys((r["look"], r["scheme"], r["tolerance"]) for r in rows))
    for look, scheme, tol in keys:
        rs = [r for r in rows if (r["look"], r["scheme"], r["tolerance"]) == (look, scheme, tol)]
        below = sum(r["below_tolerance"] for r in rs)
        worst = max(r["measured_error"] / tol for r in rs)
        ratios = [r["needed_over_chosen"] for r in rs if r["needed_over_chosen"] is not None]
        span = f"{min(ratios):.2f}–{max(ratios):.2f}" if ratios else "—"
        print(f"| {look} | {scheme} | {tol:g} | {len(rs)} | {below} | {worst:.2f} | {span} | "
              f"{max(r['pilots'] for r in rs)} | {max(r['choose_seconds'] for r in rs):.2f} |")


def stability_table(doc):
    print("\nPer hard case and integrator: forward relative RMS error against the continuous "
          "integral / float32 gradient's max error against float64 (density; TF), relative to "
          "the largest float64 entry; every value finite unless marked\n")
    rows = doc["rows"]
    columns = list(dict.fromkeys((r["model"], r["integrator"]) for r in rows))
    print("| case | " + " | ".join(f"{i} ({'abs' if m == 'absorption' else 'ea'})"
                                   for m, i in columns) + " |")
    print("|---" * (len(columns) + 1) + "|")
    for case in dict.fromkeys(r["case"] for r in rows):
        cells = []
        for m, i in columns:
            r = next((r for r in rows if (r["case"], r["model"], r["integrator"]) == (case, m, i)),
                     None)
            if r is None:
                cells.append("—")
                continue
            g = r["gradient_f32_vs_f64"]
            bad = r["nonfinite_pixels"] + r["nonfinite_gradient"]
            cells.append(f"{r['forward_relative_rms']:.0e} / {g['density']:.0e}; {g['tf']:.0e}" +
                         (f" ({bad} NaN/Inf)" if bad else ""))
        print(f"| {case} | " + " | ".join(cells) + " |")


def stability_rows(doc):
    """The stability suite's records of an ivr-bench results file as the earlier program's rows."""
    records = {r["case"]: r for r in doc["results"] if r["suite"] == "stability"}
    rows = []
    for name, r in records.items():
        if name.endswith("_gradient"):
            continue
        g = records.get(name + "_gradient", {"metrics": {}, "check": {}})
        p, m, gm = r["params"], r["metrics"], g["metrics"]
        bad = int(r.get("check", {}).get("error", 0)) + int(g.get("check", {}).get("error", 0))
        rows.append({"case": p["case"], "model": p["model"], "integrator": p["integrator"],
                     "forward_relative_rms": m.get("forward_relative_rms", float("nan")),
                     "gradient_f32_vs_f64": {
                         "density": gm.get("gradient_f32_vs_f64_density", float("nan")),
                         "tf": gm.get("gradient_f32_vs_f64_tf", float("nan"))},
                     "nonfinite_pixels": bad, "nonfinite_gradient": 0})
    return rows


def main():
    parser = argparse.ArgumentParser(description="speed-against-error and stability tables")
    parser.add_argument("results")
    parser.add_argument("--device", help="a substring of the device's name")
    args = parser.parse_args()
    with open(args.results) as f:
        doc = json.load(f)
    if doc.get("schema", "").startswith("ivr-bench/"):
        if any(r["suite"] == "stability" for r in doc["results"]):
            stability_table({"rows": stability_rows(doc)})
        if not devices(doc):
            return
    elif doc.get("benchmark") == "stability":
        stability_table(doc)
        return
    doc = accuracy_doc(doc, args.device)
    time_tables(doc)
    exact_table(doc)
    tolerance_table(doc)


if __name__ == "__main__":
    main()
