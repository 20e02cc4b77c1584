#!/usr/bin/env python3
"""torch_overhead.py — what ivr.torch costs over ivr's own session loop: the median seconds of one
training step (render, mse against a target, density gradient) through ivr.torch.Renderer and
torch.autograd, against the same step on an ivr.Session with the target on the device
(session.gradient with the mse loss: one fused pass), and of the host copies the torch path adds
(densities up, image down, dL/dimage up, gradient down), measured alone.

    IVR_LIBRARY=build/libivr.so PYTHONPATH=bindings/python /usr/bin/python3 \\
        bench/torch_overhead.py [--size 64] [--views 32] [--resolution 64] [--repeats 9] [--json F]

The torch step renders once and marches the adjoint once (two passes); the session's gradient
renders inside its adjoint (one pass with the render's primal kept), so the ratio includes that
difference as well as the copies and Python."""
import argparse
import json
import statistics
import sys
import time

import numpy as np
import torch

import ivr
import ivr.torch


def scene(views, resolution):
    return {"model": "emission_absorption",
            "tf": {"type": "piecewise_linear", "points": [
                {"density": 0.0, "color": [0.1, 0.3, 0.9], "extinction": 0.0},
                {"density": 1.0, "color": [1.0, 0.7, 0.3], "extinction": 12.0},
                {"density": 2.0, "color": [1.0, 1.0, 1.0], "extinction": 24.0}]},
            "cameras": [{"orbit": {"views": views, "radius": 2.4, "fov_y": 30,
                                   "axis": [0.3, 1, 0.2], "width": resolution,
                                   "height": resolution}}],
            "integrator": {"scheme": "trapezoid", "step": 1.0}}


def median_seconds(step, repeats):
    step()  # compiles the kernels, sizes the buffers
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        step()
        times.append(time.perf_counter() - start)
    return statistics.median(times), min(times), max(times)


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
    renderer = ivr.torch.Renderer(s)
    with torch.no_grad():
        target = renderer(torch.from_numpy(truth))
    density = torch.from_numpy(guess.copy()).requires_grad_(True)

    def torch_step():
        density.grad = None
        loss = torch.nn.functional.mse_loss(renderer(density), target)
        loss.backward()
        return density.grad

    session = ivr.Session(renderer.context, s, guess)
    session.set_target(target.numpy())

    def session_step():
        session.set_volume(guess)
        _, g = session.gradient(wrt=("density",), loss="mse")
        return g["density"].numpy()

    image_shape = tuple(target.shape)
    weights = np.ones(image_shape, np.float32)

    def copies():  # what the torch path moves between host and device, without kernels
        session.set_volume(guess)
        session.volume.numpy()
        ivr.DeviceArray.from_numpy(session, weights).numpy()

    results = {"size": a.size, "views": a.views, "resolution": a.resolution,
               "repeats": a.repeats, "device": renderer.context.device}
    for name, f in (("torch_step", torch_step), ("session_step", session_step),
                    ("host_copies", copies)):
        med, lo, hi = median_seconds(f, a.repeats)
        results[name] = {"median_s": med, "min_s": lo, "max_s": hi}
    # The two paths compute the same gradient (mse over the same image).
    g_torch = torch_step().numpy()
    g_session = session_step()
    results["gradient_max_relative_difference"] = float(
        np.abs(g_torch - g_session).max() / max(np.abs(g_session).max(), 1e-30))
    results["torch_over_session"] = results["torch_step"]["median_s"] / \
        results["session_step"]["median_s"]
    results["copies_share_of_torch_step"] = results["host_copies"]["median_s"] / \
        results["torch_step"]["median_s"]
    print(json.dumps(results, indent=2))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(results, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
