"""run.py — runs one baseline task on one case for the ivr-bench runner and reports it as JSON.

    python run.py --framework jax --task grad --case DIR --out RESULT.json [--budget S]
                  [--device cpu|gpu]

Tasks of the march frameworks (jax, drjit, torch; case "ivr-bench-scene/1"): render (image), grad
(loss and d loss / d voxel by reverse mode), tf_forward (loss and d loss / d TF parameters by
forward mode). Tasks of the projector baseline astra (astra_project.py; case "ivr-bench-tomo/1",
--device gpu only): project, backproject. The first call (tracing, compiling, warming up) is timed
on its own; then the call repeats until the budget is spent (at least --min-repeats times). Peak
memory: the process's high-water mark is reset after the first call (/proc/self/clear_refs), so
peak_increase_bytes is what the timed calls needed above the resident set they started from.
--device gpu runs the framework on its CUDA device: prepare() puts the scene there, every call
ends synchronised with the device and leaves its outputs there; they are copied to the host
(common.to_numpy) after the timed calls. The framework's own device-memory figures are recorded
as device_* fields (the RSS fields are host memory).
The outputs go to DIR/<framework>_<task>_<name>.npy; an unavailable framework (not installed, or
--device gpu without a usable GPU) writes {"available": false, "note": ...} and exits 0, so the
runner can skip it with that note.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import statistics
import sys
import time
import traceback

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from common import DEVICES, DeviceUnavailable, load_scene, outputs_to_numpy  # noqa: E402

MARCH_TASKS = ("render", "grad", "tf_forward")
# framework -> (module, its tasks); a module may add load_case (else common.load_scene),
# case_fields and INSTALL_HINT.
FRAMEWORKS = {"jax": ("jax_march", MARCH_TASKS), "drjit": ("drjit_march", MARCH_TASKS),
              "torch": ("torch_march", MARCH_TASKS),
              "astra": ("astra_project", ("project", "backproject"))}
TASKS = tuple(dict.fromkeys(t for _, tasks in FRAMEWORKS.values() for t in tasks))


def _status_kib(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


def _trim_heap() -> None:
    """Returns the first call's freed heap to the system (glibc keeps freed small and mid-sized
    blocks resident: a framework that allocates many sub-megabyte tensors, as PyTorch's eager
    autograd does, would otherwise start the timed calls from a resident set that already holds
    its whole peak, and report a peak increase of 0)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: nothing to trim
        pass


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _device_memory(module, reset: bool = False):
    """The framework's own device-memory figures (module.device_memory), or None; never raises:
    a figure that cannot be read leaves the timing intact."""
    hook = getattr(module, "device_memory", None)
    if hook is None:
        return None
    try:
        return hook(reset=reset)
    except Exception as e:  # noqa: BLE001 - memory statistics are optional
        return {"error": f"{type(e).__name__}: {e}"}


def _device_fields(before: dict, after: dict) -> dict:
    """device_* result fields from two device_memory() readings (after the first call, with the
    peak reset where the framework can; after the timed calls)."""
    if "error" in after:
        return {"device_memory_error": after["error"]}
    fields = {"device_peak_bytes": after.get("peak"), "device_peak_scope": after.get("scope")}
    if before.get("in_use") is not None:
        fields["device_bytes_before"] = before["in_use"]
        if after.get("scope") == "timed calls" and after.get("peak") is not None:
            fields["device_peak_increase_bytes"] = max(0, after["peak"] - before["in_use"])
    return fields


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--framework", required=True, choices=FRAMEWORKS)
    p.add_argument("--task", required=True, choices=TASKS)
    p.add_argument("--case", required=True, help="case directory written by ivr-bench")
    p.add_argument("--out", required=True, help="result JSON file")
    p.add_argument("--budget", type=float, default=2.0, help="seconds of timed calls")
    p.add_argument("--min-repeats", type=int, default=3)
    p.add_argument("--max-repeats", type=int, default=50)
    p.add_argument("--threads", type=int, default=0,
                   help="CPU threads (0: the framework's own); --device cpu only")
    p.add_argument("--device", choices=DEVICES, default="cpu",
                   help="where the framework computes: cpu, or gpu (its CUDA device)")
    a = p.parse_args()
    module_name, tasks = FRAMEWORKS[a.framework]
    if a.task not in tasks:
        p.error(f"--framework {a.framework} does the tasks {', '.join(tasks)}, not {a.task}")

    result = {"framework": a.framework, "task": a.task, "case": a.case, "device": a.device}

    def write(doc) -> None:
        tmp = a.out + ".tmp"
        with open(tmp, "w") as f:
            json.dump(doc, f, indent=2)
        os.replace(tmp, a.out)

    def no_gpu(e) -> int:
        result.update(available=False, note=f"{a.framework} has no GPU here: {e}")
        write(result)
        return 0

    module = None
    try:
        module = importlib.import_module(module_name)
        result["version"] = module.version(a.threads, a.device)
        result["device_name"] = module.device_name(a.device)
    except DeviceUnavailable as e:
        return no_gpu(e)
    except ImportError as e:
        hint = getattr(module, "INSTALL_HINT", "scripts/bench_setup.sh installs the baselines")
        result.update(available=False, note=f"{a.framework} is not installed ({e}); {hint}")
        write(result)
        return 0
    result["available"] = True

    gpu = a.device == "gpu"
    try:
        scene = getattr(module, "load_case", load_scene)(a.case)
        rss0 = _status_kib("VmRSS")
        start = time.perf_counter()
        # prepare() puts the scene on the device; every call() returns only once the device has
        # finished, with its outputs left on the device (converted after the timed calls).
        call = module.prepare(a.task, scene, a.device)
        out = call()
        result["first_call_s"] = time.perf_counter() - start
        result["first_call_peak_increase_bytes"] = 1024 * (_status_kib("VmHWM") - rss0)
        _trim_heap()
        result["peak_reset"] = _reset_peak()
        device_before = _device_memory(module, reset=True) if gpu else None
        rss_before = _status_kib("VmRSS")
        times = []
        spent = time.perf_counter()
        while len(times) < a.max_repeats and (
            len(times) < a.min_repeats or time.perf_counter() - spent < a.budget
        ):
            t = time.perf_counter()
            out = call()
            times.append(time.perf_counter() - t)
        peak = _status_kib("VmHWM")
        device_after = _device_memory(module) if gpu else None
        out = outputs_to_numpy(out)  # device -> host, after the clock stopped
    except DeviceUnavailable as e:  # a framework that finds out only in prepare()
        return no_gpu(e)
    except Exception as e:  # a baseline that fails is reported, not silently dropped
        result.update(ok=False, error=f"{type(e).__name__}: {e}", traceback=traceback.format_exc())
        write(result)
        return 1

    if device_after is not None:
        result.update(_device_fields(device_before or {}, device_after))
    outputs = {}
    for name, arr in out.items():
        if arr.ndim == 0:
            result[name] = float(arr)
            continue
        path = os.path.join(a.case, f"{a.framework}_{a.task}_{name}.npy")
        np.save(path, arr)
        outputs[name] = os.path.basename(path)
    result.update(
        ok=True,
        times_s=times,
        median_s=statistics.median(times),
        min_s=min(times),
        max_s=max(times),
        rss_before_bytes=1024 * rss_before,
        peak_rss_bytes=1024 * peak,
        peak_increase_bytes=1024 * max(0, peak - rss_before),
        outputs=outputs,
    )
    fields = getattr(module, "case_fields", None)
    # march_steps is an upper bound: early termination not counted.
    result.update(fields(scene) if fields else {"march_steps": int(scene.rays.n.sum())})
    write(result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
