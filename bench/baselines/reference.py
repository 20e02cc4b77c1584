"""reference.py — an independent numpy float64 version of the baselines' march (render and loss), for tests.

Written differently from the framework baselines on purpose: np.interp for the transfer function
(the same continuous piecewise-linear function, clamped at both ends), the trilinear interpolation
as a sum of eight weighted corners, and float64 throughout (from the float32 rays of common.py), so
that agreement says the baselines implement the specification rather than share a slip. Derivatives
come from central finite differences of loss() in the tests.
"""
from __future__ import annotations

import numpy as np


def _trilinear(volume: np.ndarray, u: np.ndarray) -> np.ndarray:
    """volume (nz, ny, nx); u (R, 3) voxel-index coordinates (x, y, z) → (R,) float64."""
    sizes = np.array([volume.shape[2], volume.shape[1], volume.shape[0]])
    u = np.clip(u, 0.0, sizes - 1)
    lo = np.floor(u).astype(np.int64)
    hi = np.minimum(lo + 1, sizes - 1)  # the upper neighbour is the voxel itself on the far edge
    frac = u - lo
    out = np.zeros(len(u))
    for cz in (0, 1):
        for cy in (0, 1):
            for cx in (0, 1):
                ix = hi[:, 0] if cx else lo[:, 0]
                iy = hi[:, 1] if cy else lo[:, 1]
                iz = hi[:, 2] if cz else lo[:, 2]
                w = ((frac[:, 0] if cx else 1 - frac[:, 0]) * (frac[:, 1] if cy else 1 - frac[:, 1])
                     * (frac[:, 2] if cz else 1 - frac[:, 2]))
                out += w * volume[iz, iy, ix]
    return out


def render(scene, volume=None, tf_params=None) -> np.ndarray:
    """The image (views, H, W, 4) in float64. volume / tf_params ((points, 4): r, g, b, extinction)
    default to the scene's; pass perturbed copies for finite differences."""
    vol = np.asarray(scene.volume if volume is None else volume, np.float64)
    dens = np.asarray(scene.tf[:, 0], np.float64)
    params = np.asarray(scene.tf[:, 1:5] if tf_params is None else tf_params, np.float64)
    r = scene.rays
    u0, du = r.u0.astype(np.float64), r.du.astype(np.float64)
    t0, dt, n = r.t0.astype(np.float64), r.dt.astype(np.float64), r.n
    min_t = float(scene.min_transmittance)
    R = len(t0)
    C = np.zeros((R, 3))
    T = np.ones(R)
    for i in range(int(n.max()) if R else 0):
        live = (i < n) & (T >= min_t)  # T before this sample decides whether it is taken
        if not live.any():
            break
        t = t0 + (i + 0.5) * dt
        d = _trilinear(vol, u0 + t[:, None] * du)
        values = np.stack([np.interp(d, dens, params[:, c]) for c in range(4)], axis=1)
        tau = values[:, 3] * dt
        a = 1.0 - np.exp(-tau)
        C = np.where(live[:, None], C + (T * a)[:, None] * values[:, :3], C)
        T = np.where(live, T * np.exp(-tau), T)
    bg = np.asarray(scene.background, np.float64)
    rgba = np.concatenate([C + T[:, None] * bg, (1.0 - T)[:, None]], axis=1)
    return rgba.reshape(scene.views, scene.height, scene.width, 4)


def loss(scene, volume=None, tf_params=None) -> float:
    """The "mse" loss: mean over every element of (image - target)^2."""
    diff = render(scene, volume, tf_params) - scene.target.astype(np.float64)
    return float(np.mean(diff * diff))


def grad_volume_fd(scene, h: float = 1e-6) -> np.ndarray:
    """d loss / d voxel by central differences, (nz, ny, nx) float64."""
    base = scene.volume.astype(np.float64)
    g = np.zeros_like(base)
    for idx in np.ndindex(base.shape):
        v = base.copy()
        v[idx] += h
        up = loss(scene, volume=v)
        v[idx] -= 2 * h
        g[idx] = (up - loss(scene, volume=v)) / (2 * h)
    return g


def grad_tf_fd(scene, h: float = 1e-6) -> np.ndarray:
    """d loss / d TF parameters [r, g, b, extinction] of every point by central differences."""
    base = scene.tf[:, 1:5].astype(np.float64)
    g = np.zeros_like(base)
    for idx in np.ndindex(base.shape):
        p = base.copy()
        p[idx] += h
        up = loss(scene, tf_params=p)
        p[idx] -= 2 * h
        g[idx] = (up - loss(scene, tf_params=p)) / (2 * h)
    return g
