#!/usr/bin/env python3
"""torch_overhead.py — what ivr.torch costs over ivr's own session loop: the median seconds of one
training step (render, mse against a target, density gradient) through ivr.torch.Renderer and
torch.autograd — with zero copy (images, gradients and dL/dimage shared with the device arrays,
where the device's memory is the host's) and with the copying path devices with memory of their
own take — against the same step on an ivr.Session with the target on the device
(session.gradient with the mse loss: one fused pass).

    IVR_LIBRARY=build/libivr.so PYTHONPATH=bindings/python /usr/bin/python3 \\
        bench/torch_overhead.py [--size 64] [--views 32] [--resolution 64] [--repeats 9] [--json F]

The torch step renders once and marches the adjoint once; the session's gradient renders inside
its adjoint, so the ratio includes that difference as well as the copies and Python. Steps are
timed in alternating rounds (one of each per round), so drift on a shared machine hits all alike.
"""
import argparse
import importlib.util
import json
import os
import statistics
import sys
import time

import numpy as np
import torch

import ivr
import ivr.torch


def scene(views, resolution):
    """The training example's scene (examples/python/torch_train.py), so both time one problem."""
    path = os.path.join(os.path.dirname(__file__), "../examples/python/torch_train.py")
    spec = importlib.util.spec_from_file_location("torch_train", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    return example.scene(views, resolution)


def alternating_medians(steps, repeats):
    """{name: (median, min, max) seconds} of each step, one call of each per round."""
    for f in steps.values():
        f()  # compiles the kernels, sizes the buffers
    times = {name: [] for name in steps}
    for _ in range(repeats):
        for name, f in steps.items():
            start = time.perf_counter()
            f()
            times[name].append(time.perf_counter() - start)
    return {name: (statistics.median(t), min(t), max(t)) for name, t in times.items()}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=64)
    p.add_argument("--views", type=int, default=32)
    p.add_argument("--resolution", type=int, default=64)
    p.add_argument("--repeats", type=int, default=9)
    p.add_argument("--json", help="write the figures here too")
    a = p.parse_args(argv)

    truth = ivr.phantom("shepp-logan", a.size, supersample=2)
    guess = np.full_like(truth, 0.5)
    s = scene(a.views, a.resolution)
    zero_copy = ivr.torch.Renderer(s)
    copying = ivr.torch.Renderer(s, zero_copy.context)
    copying.zero_copy = False  # the path of devices with memory of their own
    with torch.no_grad():
        target = zero_copy(torch.from_numpy(truth))

    def torch_step(renderer):
        density = torch.from_numpy(guess.copy()).requires_grad_(True)
        loss = torch.nn.functional.mse_loss(renderer(density), target)
        loss.backward()
        return density.grad

    session = ivr.Session(zero_copy.context, s, guess)
    session.set_target(target.numpy())

    def session_step():
        session.set_volume(guess)
        _, g = session.gradient(wrt=("density",), loss="mse")
        return g["density"].numpy()

    steps = {"torch_zero_copy": lambda: torch_step(zero_copy),
             "torch_copying": lambda: torch_step(copying), "session": session_step}
    results = {"size": a.size, "views": a.views, "resolution": a.resolution,
               "repeats": a.repeats, "device": zero_copy.context.device,
               "zero_copy_available": zero_copy.zero_copy}
    for name, (med, lo, hi) in alternating_medians(steps, a.repeats).items():
        results[name] = {"median_s": med, "min_s": lo, "max_s": hi}
    # Every path computes the same gradient (mse over the same image).
    g = [np.asarray(steps[name]()) for name in steps]
    scale = max(np.abs(g[2]).max(), 1e-30)
    results["gradient_max_relative_difference"] = max(
        float(np.abs(x - g[2]).max() / scale) for x in g[:2])
    for name in ("torch_zero_copy", "torch_copying"):
        results[f"{name}_over_session"] = results[name]["median_s"] / \
            results["session"]["median_s"]
    print(json.dumps(results, indent=2))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
