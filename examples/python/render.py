#!/usr/bin/env python3
"""render.py — ivr from Python: render a built-in volume, then fit the transfer function's
extinction to a target image by gradient descent on the loss (forward or adjoint mode, as the
planner picks). Runs with no arguments; PYTHONPATH=bindings/python and IVR_LIBRARY if needed."""
import numpy as np

import ivr

scene = {"volume": {"synthetic": "marschner_lobb", "dims": [32, 32, 32]},
         "model": "emission_absorption",
         "tf": {"type": "piecewise_linear", "points": [
             {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
             {"density": 0.6, "color": [1, 0.8, 0.6], "extinction": 20}]},
         "cameras": [{"eye": [1.2, 0.8, 1.5], "target": [0, 0, 0], "up": [0, 1, 0],
                      "fov_y": 40, "width": 48, "height": 48}]}

with ivr.Context() as ctx:
    target = ctx.render(scene, None)
    print("device:", ctx.device, "image:", target.shape)
    scene["tf"]["points"][1]["extinction"] = 8.0  # start away from the target's 20
    for it in range(60):
        info = {}
        loss, grads = ctx.gradient(scene, None, target, wrt="tf", info=info)
        g = grads["tf"][1, 3]  # d loss / d extinction of the second point
        scene["tf"]["points"][1]["extinction"] -= 2e4 * g
        if it % 20 == 0:
            print(f"step {it}: loss {loss:.3e}, extinction "
                  f"{scene['tf']['points'][1]['extinction']:.3f} ({info['mode']} mode)")
    final = scene["tf"]["points"][1]["extinction"]
    print(f"extinction {final:.3f} (target 20)")
    assert abs(final - 20) < 1.0, final
