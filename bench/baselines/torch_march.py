"""torch_march.py — the PyTorch baseline of ivr-bench: the march as eager tensor code, autograd and torch.func.jacfwd.

The march is the one README.md specifies ("The march"), in float32, written the way a PyTorch user
would: a Python loop over the sample index up to the scene's largest sample count, every ray at
once, gathers by indexing, rays masked past their own count and past early termination. The voxel
gradient is reverse mode (torch.autograd.grad: the graph keeps every step's tensors, which is part
of what is measured); the TF gradient is forward mode, torch.func.jacfwd (vmap of jvp over the
4·points unit tangents).

Devices: "cpu", or "gpu" = torch.device("cuda") (the current CUDA device). prepare() makes every
tensor on the device before the timed calls; every call ends with torch.cuda.synchronize() (CUDA
kernels run asynchronously) and returns its outputs as device tensors: run.py copies them to the
host after the clock stops.
"""
from __future__ import annotations

import numpy as np

from common import DeviceUnavailable

torch = None  # imported by version()


def _torch_device(device: str):
    if device != "gpu":
        return torch.device("cpu")
    if not torch.cuda.is_available():
        build = (f"a CUDA {torch.version.cuda} build: no usable GPU or driver"
                 if torch.version.cuda else "a CPU-only build")
        raise DeviceUnavailable(f"torch.cuda.is_available() is false (torch {torch.__version__}, "
                                f"{build})")
    try:
        return torch.device("cuda", torch.cuda.current_device())  # initialises CUDA
    except RuntimeError as e:  # e.g. a driver too old for this build
        raise DeviceUnavailable(f"torch cannot start CUDA: {e}") from e


def version(threads: int, device: str = "cpu") -> str:
    """Import PyTorch for `device` ("cpu": `threads` CPU threads, 0: its own choice; "gpu": CUDA,
    `threads` unused); ImportError when it is missing, DeviceUnavailable when it has no GPU."""
    global torch
    import torch as _torch

    torch = _torch
    if device == "gpu":
        dev = _torch_device(device)
        name = torch.cuda.get_device_name(dev)
        return f"torch {torch.__version__}, cuda {torch.version.cuda}, {name}"
    if threads > 0:
        torch.set_num_threads(threads)
    return f"torch {torch.__version__}, cpu, {torch.get_num_threads()} threads"


def device_name(device: str = "cpu") -> str:
    """torch.cuda.get_device_name() on the GPU, "cpu" on the CPU."""
    dev = _torch_device(device)
    return torch.cuda.get_device_name(dev) if dev.type == "cuda" else "cpu"


def device_memory(reset: bool = False):
    """The CUDA caching allocator's figures: bytes allocated and their high-water mark since the
    last reset (reset=True starts a new one, so the peak covers the timed calls)."""
    if not torch.cuda.is_available():
        return None
    torch.cuda.synchronize()
    stats = {"in_use": torch.cuda.memory_allocated(), "peak": torch.cuda.max_memory_allocated(),
             "scope": "timed calls"}
    if reset:
        torch.cuda.reset_peak_memory_stats()
    return stats


def _sync(device) -> None:
    """Waits for the device's queued kernels (CUDA runs them asynchronously; the CPU does not)."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def _lerp(a, b, t):
    return a + (b - a) * t  # ivr's form (not a·(1−t) + b·t): same rounding


def _march(volume, tf_values, tf_density, rays, background, min_t, max_n):
    """RGBA (R, 4) of every ray. volume (nz, ny, nx); tf_values (points, 4) [r, g, b, extinction]."""
    u0, du, t0, dt, n = rays
    nz, ny, nx = volume.shape
    dev = volume.device
    flat = volume.reshape(-1)
    upper = torch.tensor([nx - 1, ny - 1, nz - 1], dtype=torch.float32, device=dev)
    points = tf_density.shape[0]
    R = t0.shape[0]
    C = torch.zeros(R, 3, device=dev)
    T = torch.ones(R, device=dev)
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


def prepare(task: str, scene, device: str = "cpu"):
    """Returns call() for `task` on `scene`: the tensors are made on `device` before it is timed;
    call() returns the outputs as device tensors, computed (synchronised)."""
    dev = _torch_device(device)

    def tensor(a):
        return torch.from_numpy(np.ascontiguousarray(a).copy()).to(dev)

    r = scene.rays
    rays = tuple(tensor(a) for a in (r.u0, r.du, r.t0, r.dt, r.n))
    volume = tensor(scene.volume)
    tf_density = tensor(scene.tf[:, 0])
    tf_values = tensor(scene.tf_parameters)
    background = tensor(scene.background)
    target = tensor(scene.target)
    _sync(dev)  # the uploads are done before the first call
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
                img = image(volume, tf_values)
            _sync(dev)
            return {"image": img}

    elif task == "grad":
        def call():
            vol = volume.detach().requires_grad_(True)
            value = loss(vol, tf_values)
            (g,) = torch.autograd.grad(value, vol)
            _sync(dev)
            return {"loss": value.detach(), "grad": g}

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
            _sync(dev)
            return {"loss": value.detach(), "tf_grad": g.detach()}

    else:
        raise ValueError(f"unknown task {task!r}")
    return call
