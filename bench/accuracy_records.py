"""accuracy_records.py — the speed-against-error results as plot_accuracy.py and accuracy_tables.py
read them, from `ivr-bench --suite integrators` (one device's records) or from the JSON of the
earlier ivr_accuracy_bench program (bench/results/accuracy_*.json), which is returned as it is.

The shape (the earlier program's): device, image, views, reference; rows (volume, look,
integrator, step, relative_rms, relative_max, ms, samples); time_at_target (volume, look,
integrator, target_relative_rms, ms_at_target); best_against_midpoint (volume, look, best,
ms_at_target, midpoint_ms_at_target, speedup); exact (volume, step, f32/f64 relative_rms and
relative_max); tolerance (volume, look, scheme, tolerance, step, estimated_error, measured_error,
below_tolerance, needed_step, needed_over_chosen, pilots, choose_seconds).
"""

SUITE = "integrators"


def _label(key):
    """A time-at-target metric's integrator key ("midpoint_skip") as the plots' label."""
    return key[:-len("_skip")] + "+skip" if key.endswith("_skip") else key


def devices(doc):
    """The devices of an ivr-bench results file with integrators records, in order."""
    return list(dict.fromkeys(r["device"] for r in doc.get("results", [])
                              if r["suite"] == SUITE and r["implementation"] == "ivr"))


def accuracy_doc(doc, device=None):
    """The results of one device (the first with integrators records, or the first whose name
    contains `device`) in the shape above; an earlier program's document unchanged."""
    if not doc.get("schema", "").startswith("ivr-bench/"):
        return doc
    names = [d for d in devices(doc) if device is None or device in d]
    if not names:
        raise SystemExit(f"no integrators records{' for ' + device if device else ''} in the file")
    records = [r for r in doc["results"]
               if r["suite"] == SUITE and r["device"] == names[0] and r["implementation"] == "ivr"]
    out = {"device": names[0], "image": None, "views": None,
           "reference": "reference/ render_continuous (float64)",
           "rows": [], "time_at_target": [], "best_against_midpoint": [], "exact": [],
           "tolerance": []}
    for r in records:
        p, m = r["params"], r["metrics"]
        out["image"] = out["image"] or p.get("image")
        out["views"] = out["views"] or p.get("views")
        if "integrator" in p and "error_relative_l2" in m and "device_median_s" in m:
            out["rows"].append({"volume": p["volume"], "look": p["look"],
                                "integrator": p["integrator"], "step": p["step"],
                                "relative_rms": m["error_relative_l2"],
                                "relative_max": m["error_relative_max"],
                                "ms": 1e3 * m["device_median_s"], "samples": m["samples"]})
            if p["scheme"] == "exact" and p["empty_space"] == "off":
                out["exact"].append({
                    "volume": p["volume"], "step": p["step"],
                    "f32": {"relative_rms": m["error_relative_l2"],
                            "relative_max": m["error_relative_max"]},
                    "f64": {"relative_rms": m["error_relative_l2_f64"],
                            "relative_max": m["error_relative_max_f64"]}})
        elif r["case"].endswith("_time_at_target"):
            target = p["target_relative_l2"]
            times = {_label(k[:-len("_s_at_target")]): v for k, v in m.items()
                     if k.endswith("_s_at_target") and k != "best_s_at_target"}
            for integrator in dict.fromkeys(row["integrator"] for row in out["rows"]
                                            if (row["volume"], row["look"]) ==
                                            (p["volume"], p["look"])):
                t = times.get(integrator)
                out["time_at_target"].append({"volume": p["volume"], "look": p["look"],
                                              "integrator": integrator,
                                              "target_relative_rms": target,
                                              "ms_at_target": None if t is None else 1e3 * t})
            best = min(times, key=times.get) if times else None
            mid = times.get("midpoint")
            out["best_against_midpoint"].append({
                "volume": p["volume"], "look": p["look"], "best": best,
                "ms_at_target": None if best is None else 1e3 * times[best],
                "midpoint_ms_at_target": None if mid is None else 1e3 * mid,
                "speedup": m.get("midpoint_over_best")})
        elif "tolerance" in p and "check" in r:
            c = r["check"]
            out["tolerance"].append({"volume": p["volume"], "look": p["look"],
                                     "scheme": p["scheme"], "tolerance": p["tolerance"],
                                     "step": m.get("chosen_step"),
                                     "estimated_error": m.get("estimated_error"),
                                     "measured_error": c["error"], "below_tolerance": c["passed"],
                                     "needed_step": m.get("needed_step"),
                                     "needed_over_chosen": m.get("needed_over_chosen"),
                                     "pilots": m.get("pilots", 0),
                                     "choose_seconds": m.get("median_s", float("nan"))})
    return out
