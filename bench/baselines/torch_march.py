"""torch_march.py — the PyTorch baseline of ivr-bench: the march as eager tensor code, autograd and torch.func.jacfwd.

The march is the one README.md specifies ("The march"), in float32, written the way a PyTorch user
would: a Python loop over the sample index up to the scene's largest sample count, every ray at
once, gathers by indexing, rays masked past their own count and past early termination. The voxel
gradient is reverse mode (torch.autograd.grad: the graph keeps every step's tensors, which is part
of what is measured); the TF gradient is forward mode, torch.func.jacfwd (vmap of jvp over the
4·points unit tangents).
"""
from __future__ import annotations

import numpy as np

torch = None  # imported by version()


def version(threads: int) -> str:
    """Import PyTorch and use `threads` CPU threads (0: its own choice); ImportError when missing."""
    global torch
    import torch as _torch

    torch = _torch
    if threads > 0:
        torch.set_num_threads(threads)
    return f"torch {torch.__version__}, cpu, {torch.get_num_threads()} threads"


def _lerp(a, b, t):
    return a + (b - a) * t  # ivr's form (not a·(1−t) + b·t): same rounding


def _march(volume, tf_values, tf_density, rays, background, min_t, max_n):
    """RGBA (R, 4) of every ray. volume (nz, ny, nx); tf_values (points, 4) [r, g, b, extinction]."""
    u0, du, t0, dt, n = rays
    nz, ny, nx = volume.shape
    flat = volume.reshape(-1)
    upper = torch.tensor([nx - 1, ny - 1, nz - 1], dtype=torch.float32)
    points = tf_density.shape[0]
    R = t0.shape[0]
    C = torch.zeros(R, 3)
    T = torch.ones(R)
    for i in range(max_n):
        t = t0 + (i + 0.5) * dt
        u = torch.minimum(torch.clamp(u0 + t[:, None] * du, min=0), upper)
        i0 = u.long()  # u ≥ 0, so truncation is floor
        f = u - i0.float()
        x0, y0, z0 = i0[:, 0], i0[:, 1], i0[:, 2]
        # Offsets of the +1 neighbours: 0 on the upper edge (the voxel itself), as ivr's kernel.
        ox = (x0 + 1 < nx).long()
        oy = (y0 + 1 < ny).long() * nx
        oz = (z0 + 1 < nz).long() * (nx * ny)
        base = (z0 * ny + y0) * nx + x0
        fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
        c00, c10 = _lerp(flat[base], flat[base + ox], fx), _lerp(flat[base + oy], flat[base + oy + ox], fx)
        c01 = _lerp(flat[base + oz], flat[base + oz + ox], fx)
        c11 = _lerp(flat[base + oz + oy], flat[base + oz + oy + ox], fx)
        d = _lerp(_lerp(c00, c10, fy), _lerp(c01, c11, fy), fz)
        # The TF: segment k with d_k ≤ d < d_k+1; both ends clamp to their point's values exactly
        # (a = b, w = 0), so the clamped branches carry no derivative w.r.t. d.
        k = torch.clamp(torch.searchsorted(tf_density, d.detach(), right=True) - 1, 0, points - 2)
        above = d >= tf_density[-1]
        inside = (d > tf_density[0]) & ~above
        ka = torch.where(above, points - 1, torch.where(inside, k, 0))
        kb = torch.where(above, points - 1, torch.where(inside, k + 1, 0))
        w = torch.where(inside, (d - tf_density[k]) / (tf_density[k + 1] - tf_density[k]), 0.0)
        v = _lerp(tf_values[ka], tf_values[kb], w[:, None])
        tau = v[:, 3] * dt
        # A mask, not a break: a sample is taken while the ray has it and T (before it) ≥ min_t.
        live = (i < n) & (T >= min_t)
        C = torch.where(live[:, None], C + (T * -torch.expm1(-tau))[:, None] * v[:, :3], C)
        T = torch.where(live, T * torch.exp(-tau), T)
    return torch.cat([C + T[:, None] * background, (1 - T)[:, None]], dim=1)


def prepare(task: str, scene):
    """Returns call() for `task` on `scene`; the tensors are made before it is timed."""
    r = scene.rays
    rays = tuple(torch.from_numpy(np.ascontiguousarray(a)) for a in (r.u0, r.du, r.t0, r.dt, r.n))
    volume = torch.from_numpy(scene.volume.copy())
    tf_density = torch.from_numpy(scene.tf[:, 0].copy())
    tf_values = torch.from_numpy(scene.tf_parameters)
    background = torch.from_numpy(scene.background.copy())
    target = torch.from_numpy(scene.target.copy())
    shape = scene.target.shape
    min_t, max_n = float(scene.min_transmittance), scene.max_samples
    if scene.loss != "mse":
        raise NotImplementedError(f"loss {scene.loss!r}: only 'mse' is implemented")

    def image(vol, values):
        return _march(vol, values, tf_density, rays, background, min_t, max_n).reshape(shape)

    def loss(vol, values):
        diff = image(vol, values) - target
        return torch.mean(diff * diff)

    if task == "render":
        def call():
            with torch.no_grad():
                return {"image": image(volume, tf_values).numpy()}

    elif task == "grad":
        def call():
            vol = volume.detach().requires_grad_(True)
            value = loss(vol, tf_values)
            (g,) = torch.autograd.grad(value, vol)
            return {"loss": float(value.detach()), "grad": g.numpy()}

    elif task == "tf_forward":
        try:
            from torch.func import jacfwd
        except ImportError as e:  # torch < 2.0
            raise NotImplementedError(f"torch {torch.__version__} has no torch.func ({e})") from e

        def loss_aux(values):
            value = loss(volume, values)
            return value, value

        fn = jacfwd(loss_aux, has_aux=True)

        def call():
            try:
                g, value = fn(tf_values)
            except RuntimeError as e:  # an op without a forward-mode or vmap rule
                raise NotImplementedError(f"torch.func.jacfwd failed on the march: {e}") from e
            return {"loss": float(value), "tf_grad": g.detach().numpy()}

    else:
        raise ValueError(f"unknown task {task!r}")
    return call
