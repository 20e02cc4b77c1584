#!/usr/bin/env python3
"""torch_function.py — ivr inside PyTorch: a torch.autograd.Function whose forward renders a
volume and whose backward is ivr's adjoint (d loss / d density), so that a torch optimiser can
reconstruct a volume from images. Exits 0 with a note when torch is not installed."""
import sys

import numpy as np

import ivr

try:
    import torch
except ImportError:
    print("torch is not installed: skipping the PyTorch example")
    sys.exit(0)


class RenderLoss(torch.autograd.Function):
    """mse(render(volume), target) with ivr's gradient in backward."""

    @staticmethod
    def forward(ctx, volume, target, context, scene):
        v = volume.detach().cpu().numpy().astype(np.float32)
        loss, grads = context.gradient(scene, v, target.cpu().numpy(), wrt="density", mode="adjoint")
        ctx.save_for_backward(torch.from_numpy(grads["density"].astype(np.float32)))
        return volume.new_tensor(loss)

    @staticmethod
    def backward(ctx, grad_output):
        (g,) = ctx.saved_tensors
        return grad_output * g, None, None, None


def main():
    scene = {"model": "absorption", "tf": {"type": "identity", "extinction_scale": 4},
             "cameras": [{"eye": e, "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40,
                          "width": 24, "height": 24}
                         for e in ([0, 0, 2], [2, 0, 0.3], [0.3, 2, 0])]}
    z, y, x = np.mgrid[-1:1:16j, -1:1:16j, -1:1:16j]
    truth = np.clip(1 - np.sqrt(x**2 + y**2 + z**2), 0, 1).astype(np.float32)
    with ivr.Context() as context:
        target = torch.from_numpy(context.render(scene, truth))
        volume = torch.full(truth.shape, 0.3, requires_grad=True)
        opt = torch.optim.Adam([volume], lr=0.02)
        first = None
        for it in range(40):
            opt.zero_grad()
            loss = RenderLoss.apply(volume, target, context, scene)
            loss.backward()
            opt.step()
            with torch.no_grad():
                volume.clamp_(0, 1)
            first = first if first is not None else loss.item()
        print(f"loss {first:.3e} -> {loss.item():.3e}")
        assert loss.item() < 0.5 * first


if __name__ == "__main__":
    main()
