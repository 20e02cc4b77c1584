#!/usr/bin/env python3
"""torch_train.py — fit a volume's densities to images with torch.optim.Adam through
ivr.torch.Renderer: by default a 64³ volume to 32 views (64² each) of the Shepp–Logan phantom
rendered through an emission–absorption TF, until the loss is below 1 % of its start.

    python3 examples/python/torch_train.py [--size 64] [--views 32] [--resolution 64]
                                           [--iterations 100] [--lr 0.05]

Prints the loss as it falls, the time per iteration and the relative volume error; exits 1 if
the last loss is not below 1 % of the first."""
import argparse
import sys
import time

import numpy as np
import torch

import ivr
import ivr.torch


def scene(views, resolution):
    """Cameras on an orbit around the default box, an emission–absorption TF."""
    return {"model": "emission_absorption",
            "tf": {"type": "piecewise_linear", "points": [
                {"density": 0.0, "color": [0.1, 0.3, 0.9], "extinction": 0.0},
                {"density": 1.0, "color": [1.0, 0.7, 0.3], "extinction": 12.0},
                {"density": 2.0, "color": [1.0, 1.0, 1.0], "extinction": 24.0}]},
            "background": [0.0, 0.0, 0.0],
            "cameras": [{"orbit": {"views": views, "radius": 2.4, "fov_y": 30, "axis": [0.3, 1, 0.2],
                                   "width": resolution, "height": resolution}}],
            "integrator": {"scheme": "trapezoid", "step": 1.0}}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=64, help="voxels per axis")
    parser.add_argument("--views", type=int, default=32)
    parser.add_argument("--resolution", type=int, default=64, help="pixels per image side")
    parser.add_argument("--iterations", type=int, default=100)
    parser.add_argument("--lr", type=float, default=0.05)
    args = parser.parse_args(argv)

    truth = torch.from_numpy(ivr.phantom("shepp-logan", args.size, supersample=2))
    renderer = ivr.torch.Renderer(scene(args.views, args.resolution))
    print(f"ivr on {renderer.context.device}: {args.size}³ volume, {args.views} views of "
          f"{args.resolution}²")
    with torch.no_grad():
        target = renderer(truth)  # the images to fit: (views, H, W, 4)

    density = torch.full_like(truth, 0.5, requires_grad=True)
    optimizer = torch.optim.Adam([density], lr=args.lr)
    losses, start = [], time.perf_counter()
    every = max(args.iterations // 10, 1)
    for it in range(args.iterations):
        optimizer.zero_grad()
        loss = torch.nn.functional.mse_loss(renderer(density), target)
        loss.backward()  # ivr's adjoint: the density gradient of every voxel at once
        optimizer.step()
        with torch.no_grad():
            density.clamp_(min=0)  # densities are >= 0
        losses.append(loss.item())
        if it % every == 0 or it == args.iterations - 1:
            print(f"iteration {it + 1:4d}  loss {losses[-1]:.4e}")
    seconds = (time.perf_counter() - start) / args.iterations
    error = float((density.detach() - truth).norm() / truth.norm())
    ratio = losses[-1] / losses[0]
    print(f"loss {losses[0]:.4e} -> {losses[-1]:.4e}: {100 * ratio:.2g} % of its start; "
          f"{1000 * seconds:.0f} ms per iteration; relative volume error {error:.3f}")
    return 0 if ratio < 0.01 else 1


if __name__ == "__main__":
    sys.exit(main())
