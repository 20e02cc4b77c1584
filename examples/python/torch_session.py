#!/usr/bin/env python3
"""torch_session.py — ivr inside PyTorch over one device-resident session: a
torch.autograd.Function whose forward sets the volume into a Session made once beforehand and
returns the loss of session.gradient against the session's target, and whose backward is that
density gradient; torch.optim.Adam then reconstructs a small volume from its renders.

    python3 examples/python/torch_session.py [--iterations 40] [--size 16]

Importable (SessionLoss, make_problem, reconstruct); run without torch it says so and exits 0."""
import argparse
import sys

import numpy as np

import ivr

try:
    import torch
except ImportError:  # the module stays importable; main() reports it
    torch = None

if torch is not None:
    class SessionLoss(torch.autograd.Function):
        """loss(volume) = session's loss of render(volume) against its target, with ivr's density
        gradient (adjoint mode) as the backward. The session is made once, outside: each forward
        only uploads the densities (checked there: finite, >= 0)."""

        @staticmethod
        def forward(ctx, volume, session, mode="adjoint"):
            session.set_volume(volume.detach().cpu().numpy())
            loss, grads = session.gradient(wrt=("density",), mode=mode)
            density = torch.from_numpy(grads["density"].numpy())
            ctx.save_for_backward(density.to(dtype=volume.dtype, device=volume.device))
            return volume.new_tensor(float(loss))

        @staticmethod
        def backward(ctx, grad_output):
            (density,) = ctx.saved_tensors
            return grad_output * density, None, None


def scene(size=16, views=4, resolution=24):
    """An emission-absorption scene of `views` cameras on an orbit (the volume comes apart)."""
    return {"model": "emission_absorption",
            "tf": {"type": "piecewise_linear", "points": [
                {"density": 0.0, "color": [0.2, 0.4, 0.9], "extinction": 0.5},
                {"density": 1.0, "color": [1.0, 0.6, 0.2], "extinction": 8.0}]},
            "background": [0.05, 0.05, 0.05],
            "cameras": [{"orbit": {"views": views, "radius": 2.2, "fov_y": 35,
                                   "width": resolution, "height": resolution}}],
            "integrator": {"scheme": "trapezoid", "step": 0.5}}


def truth(size=16):
    """Two overlapping soft balls, float32 (size, size, size) in [0, 1]."""
    z, y, x = np.mgrid[-1:1:size * 1j, -1:1:size * 1j, -1:1:size * 1j]
    a = np.clip(1 - 2.2 * np.sqrt((x - 0.25) ** 2 + y**2 + z**2), 0, 1)
    b = np.clip(1 - 3.0 * np.sqrt((x + 0.35) ** 2 + (y - 0.2) ** 2 + (z + 0.1) ** 2), 0, 1)
    return np.maximum(a, 0.7 * b).astype(np.float32)


def make_problem(context, size=16, views=4, resolution=24):
    """(session, truth): a session of the scene whose target is the render of the true volume."""
    s = scene(size, views, resolution)
    true = truth(size)
    session = ivr.Session(context, s, true)
    session.set_target(session.render())  # the target stays on the device
    return session, true


def reconstruct(session, start, iterations=40, lr=0.03, progress=None):
    """Adam on the densities from `start` through SessionLoss; returns (volume, losses)."""
    volume = torch.tensor(start, dtype=torch.float32, requires_grad=True)
    opt = torch.optim.Adam([volume], lr=lr)
    losses = []
    for it in range(iterations):
        opt.zero_grad()
        loss = SessionLoss.apply(volume, session)
        loss.backward()
        opt.step()
        with torch.no_grad():
            volume.clamp_(min=0)  # densities are >= 0 (set_volume refuses negative ones)
        losses.append(loss.item())
        if progress:
            progress(it, losses[-1])
    return volume.detach(), losses


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--iterations", type=int, default=40)
    parser.add_argument("--size", type=int, default=16, help="voxels per axis")
    parser.add_argument("--lr", type=float, default=0.03)
    args = parser.parse_args(argv)
    if torch is None:
        print("torch is not installed: skipping the PyTorch session example")
        return 0
    with ivr.Context() as context:
        session, true = make_problem(context, args.size)
        start = np.full(true.shape, 0.2, np.float32)
        every = max(args.iterations // 8, 1)

        def show(it, loss):
            if it % every == 0 or it == args.iterations - 1:
                print(f"iteration {it + 1:4d}  loss {loss:.4e}")
        volume, losses = reconstruct(session, start, args.iterations, args.lr, show)
        error = np.linalg.norm(volume.numpy() - true) / np.linalg.norm(true)
        print(f"loss {losses[0]:.3e} -> {losses[-1]:.3e}; relative volume error {error:.3f}")
        session.close()
        return 0 if losses[-1] < losses[0] else 1


if __name__ == "__main__":
    sys.exit(main())
