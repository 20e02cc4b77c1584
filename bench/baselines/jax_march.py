"""jax_march.py — the JAX baseline of ivr-bench: the march in jax.numpy (lax.scan, jit), jax.grad and jax.jacfwd.

The march is the one README.md specifies ("The march"), in float32, for every ray at once: a
lax.scan over the sample index up to the scene's largest sample count, rays masked past their own
count and past early termination. Derivatives are what a JAX user writes: jax.value_and_grad of the
loss for the voxels (reverse mode; the scan keeps its residuals for every step, which is part of
what is measured) and jax.jacfwd (a vmap of jvp over the 4·points unit tangents) for the TF.

Devices: "cpu" (JAX_PLATFORMS=cpu, the thread count by CPU affinity) or "gpu" (the first of
jax.devices("gpu"): needs a CUDA jaxlib). prepare() commits every input to the device with
jax.device_put before the timed calls, so the jitted functions run there; every call ends with
jax.block_until_ready on its outputs (JAX dispatches asynchronously, on the CPU too) and returns
them as device arrays: run.py copies them to the host after the clock stops.
"""
from __future__ import annotations

import os

import numpy as np

from common import DeviceUnavailable

jax = None  # imported by version(), after the thread count is set
jnp = None


def version(threads: int, device: str = "cpu") -> str:
    """Import JAX for `device` ("cpu": with `threads` CPU threads, 0: its own choice; "gpu": its
    CUDA backend, `threads` unused); ImportError when JAX is missing, DeviceUnavailable when it has
    no GPU."""
    global jax, jnp
    if device == "gpu":
        # Platforms named explicitly: a CUDA jaxlib that fails to start then says why, instead of
        # JAX quietly falling back to the CPU. Memory grows on demand (JAX would otherwise take 75%
        # of the GPU at start-up, next to whatever the ivr-bench process holds).
        if os.environ.get("JAX_PLATFORMS", "cpu") == "cpu":
            os.environ["JAX_PLATFORMS"] = "cuda,cpu"
        os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")
    elif threads > 0:
        # XLA's CPU thread pool is sized from the CPUs this process may run on, and no JAX setting
        # caps it, so the process is pinned to `threads` of them (before the backend starts).
        cpus = sorted(os.sched_getaffinity(0))
        if threads < len(cpus):
            os.sched_setaffinity(0, cpus[:threads])
        if threads == 1:
            flags = os.environ.get("XLA_FLAGS", "")
            os.environ["XLA_FLAGS"] = (flags + " --xla_cpu_multi_thread_eigen=false"
                                       " intra_op_parallelism_threads=1").strip()
    if device != "gpu":
        os.environ.setdefault("JAX_PLATFORMS", "cpu")
    import jax as _jax
    import jax.numpy as _jnp
    import jaxlib

    jax, jnp = _jax, _jnp
    jax.config.update("jax_enable_x64", False)  # float32 everywhere, as ivr
    where = f"{len(os.sched_getaffinity(0))} cpus"
    if device == "gpu":
        dev = _device("gpu")
        where = f"{dev.platform} device {dev.id}: {dev.device_kind}"
    return f"jax {jax.__version__}, jaxlib {jaxlib.__version__}, {jax.default_backend()}, {where}"


def _device(device: str):
    """The jax.Device that `device` ("cpu" or "gpu") means: the first of its kind."""
    if device != "gpu":
        return jax.devices("cpu")[0]
    try:
        return jax.devices("gpu")[0]
    # RuntimeError: "Unknown backend: 'gpu' requested, but no platforms ..." (a CPU-only jaxlib),
    # "Unable to initialize backend 'cuda': ..." (a CUDA plugin without a usable driver/GPU); other
    # errors come from platforms JAX does not know (JAX_PLATFORMS=cuda with a CPU-only jaxlib).
    except Exception as e:  # noqa: BLE001 - whatever keeps JAX off the GPU, say why
        platforms = os.environ.get("JAX_PLATFORMS", "")
        raise DeviceUnavailable(f"jax {jax.__version__} has no CUDA device (a CPU-only jaxlib, "
                                f"or no usable GPU/driver; JAX_PLATFORMS={platforms!r}): "
                                f"{type(e).__name__}: {e}") from e


def device_name(device: str = "cpu") -> str:
    """JAX's name for the device: its device_kind ("cpu", "NVIDIA H100 80GB HBM3", ...)."""
    return _device(device).device_kind


def device_memory(reset: bool = False):
    """The GPU's memory figures from JAX's allocator: bytes in use and the high-water mark. JAX
    cannot reset the high-water mark, so it covers the whole process (first call included)."""
    stats = _device("gpu").memory_stats() or {}
    if "peak_bytes_in_use" not in stats:
        return None
    return {"in_use": stats.get("bytes_in_use"), "peak": stats["peak_bytes_in_use"],
            "scope": "process"}


def _lerp(a, b, t):
    return a + (b - a) * t  # ivr's form (not a·(1−t) + b·t): same rounding


def _march(volume, tf_values, tf_density, u0, du, t0, dt, n, background, *, min_t, max_n):
    """RGBA (R, 4) of every ray. volume (nz, ny, nx); tf_values (points, 4) [r, g, b, extinction]."""
    f32 = jnp.float32
    nz, ny, nx = volume.shape
    flat = volume.reshape(-1)
    upper = jnp.array([nx - 1, ny - 1, nz - 1], f32)
    points = tf_density.shape[0]
    R = t0.shape[0]

    def sample(carry, i):
        C, T = carry
        t = t0 + (i.astype(f32) + f32(0.5)) * dt
        u = jnp.clip(u0 + t[:, None] * du, 0, upper)
        i0 = u.astype(jnp.int32)  # u ≥ 0, so truncation is floor
        f = u - i0.astype(f32)
        x0, y0, z0 = i0[:, 0], i0[:, 1], i0[:, 2]
        # Offsets of the +1 neighbours: 0 on the upper edge (the voxel itself), as ivr's kernel.
        ox = jnp.where(x0 + 1 < nx, 1, 0)
        oy = jnp.where(y0 + 1 < ny, nx, 0)
        oz = jnp.where(z0 + 1 < nz, nx * ny, 0)
        base = (z0 * ny + y0) * nx + x0
        p = lambda o: flat[base + o]  # noqa: E731 - a gather per corner
        fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
        c00, c10 = _lerp(p(0), p(ox), fx), _lerp(p(oy), p(oy + ox), fx)
        c01, c11 = _lerp(p(oz), p(oz + ox), fx), _lerp(p(oz + oy), p(oz + oy + ox), fx)
        d = _lerp(_lerp(c00, c10, fy), _lerp(c01, c11, fy), fz)
        # The TF: segment k with d_k ≤ d < d_k+1; both ends clamp to their point's values exactly
        # (a = b, w = 0), so the clamped branches carry no derivative w.r.t. d.
        k = jnp.clip(jnp.searchsorted(tf_density, d, side="right") - 1, 0, points - 2)
        above = d >= tf_density[points - 1]
        inside = (d > tf_density[0]) & ~above
        ka = jnp.where(above, points - 1, jnp.where(inside, k, 0))
        kb = jnp.where(above, points - 1, jnp.where(inside, k + 1, 0))
        w = jnp.where(inside, (d - tf_density[k]) / (tf_density[k + 1] - tf_density[k]), f32(0))
        v = _lerp(tf_values[ka], tf_values[kb], w[:, None])
        tau = v[:, 3] * dt
        # A mask, not a break: a sample is taken while the ray has it and T (before it) ≥ min_t.
        live = (i < n) & (T >= min_t)
        C = jnp.where(live[:, None], C + (T * -jnp.expm1(-tau))[:, None] * v[:, :3], C)
        T = jnp.where(live, T * jnp.exp(-tau), T)
        return (C, T), None

    init = (jnp.zeros((R, 3), f32), jnp.ones((R,), f32))
    (C, T), _ = jax.lax.scan(sample, init, jnp.arange(max_n, dtype=jnp.int32))
    return jnp.concatenate([C + T[:, None] * background, (1 - T)[:, None]], axis=1)


def prepare(task: str, scene, device: str = "cpu"):
    """Returns call() for `task` on `scene`: the inputs are committed to `device` before it is
    timed; call() returns the outputs as device arrays, computed (block_until_ready)."""
    r = scene.rays
    dev = _device(device)

    def put(a):
        return jax.device_put(a, dev)

    rays = tuple(put(a) for a in (r.u0, r.du, r.t0, r.dt, r.n))
    volume = put(scene.volume)
    tf_density = put(scene.tf[:, 0].copy())
    tf_values = put(scene.tf_parameters)
    background = put(scene.background)
    target = put(scene.target)
    shape = scene.target.shape
    min_t, max_n = np.float32(scene.min_transmittance), scene.max_samples
    if scene.loss != "mse":
        raise NotImplementedError(f"loss {scene.loss!r}: only 'mse' is implemented")

    def image(vol, values, rays, bg):
        rgba = _march(vol, values, tf_density, *rays, bg, min_t=min_t, max_n=max_n)
        return rgba.reshape(shape)

    def loss(vol, values, rays, bg, tgt):
        diff = image(vol, values, rays, bg) - tgt
        return jnp.mean(diff * diff)

    if task == "render":
        fn = jax.jit(image)

        def call():
            return {"image": jax.block_until_ready(fn(volume, tf_values, rays, background))}

    elif task == "grad":
        fn = jax.jit(jax.value_and_grad(loss, argnums=0))

        def call():
            value, g = jax.block_until_ready(fn(volume, tf_values, rays, background, target))
            return {"loss": value, "grad": g}

    elif task == "tf_forward":
        # jacfwd of a scalar over the (points, 4) parameters: one jvp per unit tangent, vmapped.
        def loss_aux(values, vol, rays, bg, tgt):
            value = loss(vol, values, rays, bg, tgt)
            return value, value

        fn = jax.jit(jax.jacfwd(loss_aux, argnums=0, has_aux=True))

        def call():
            g, value = jax.block_until_ready(fn(tf_values, volume, rays, background, target))
            return {"loss": value, "tf_grad": g}

    else:
        raise ValueError(f"unknown task {task!r}")
    return call
