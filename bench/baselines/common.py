"""common.py — the scene every baseline marches, read from the runner's scene.json, and its rays.

The ivr-bench runner writes a case directory with scene.json (format "ivr-bench-scene/1"),
volume.npy (float32, (nz, ny, nx)) and target.npy (float32, (views, H, W, 4)); every baseline
computes the same emission–absorption march of it (see README.md, "The march"). Rays are set up
here once in numpy float32 (outside the timed region, for every framework alike): what is timed is
the march and its derivatives. A call's outputs stay where the framework computed them (on the GPU
with --device gpu); to_numpy() brings them to the host after the timed region.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass

import numpy as np

SCENE_FORMAT = "ivr-bench-scene/1"
DEVICES = ("cpu", "gpu")


class DeviceUnavailable(Exception):
    """Raised by a baseline's version()/prepare() when the framework is installed but cannot use the
    device asked for (e.g. no CUDA build, no GPU); run.py reports it as "available": false."""


class Deferred:
    """An output the timed call leaves where the framework computed it (e.g. on the GPU), to be
    turned into numpy by to_numpy() after the clock stops: `fetch()` returns the host value (a
    numpy array, a Python scalar or a framework array). For outputs that need more than a plain
    conversion (Dr.Jit's image is four channel arrays stacked and reshaped on the host)."""

    __slots__ = ("fetch",)

    def __init__(self, fetch):
        self.fetch = fetch


def to_numpy(value) -> np.ndarray:
    """A baseline's output as a numpy array (0-d for scalars), copied to the host if it is on a
    device: numpy arrays and Python scalars as they are, Deferred outputs fetched, torch tensors by
    .detach().cpu().numpy(), JAX and Dr.Jit arrays (CPU or GPU) by np.asarray. No framework is
    imported here: the type is told by its module."""
    if isinstance(value, Deferred):
        value = value.fetch()
    root = type(value).__module__.split(".")[0]
    if root == "torch":  # np.asarray refuses CUDA tensors and tensors that require grad
        value = value.detach().cpu().numpy()
    return np.asarray(value)  # jax.Array and drjit arrays implement __array__ (device -> host)


def outputs_to_numpy(outputs: dict) -> dict:
    """to_numpy() of every entry of a call()'s result dict."""
    return {name: to_numpy(value) for name, value in outputs.items()}


@dataclass
class Rays:
    """One entry per pixel of every view, in pixel order (view, y, x)."""

    u0: np.ndarray  # (R, 3) float32: voxel-index coordinates of the eye, minus 0.5 (x, y, z)
    du: np.ndarray  # (R, 3) float32: ray direction in voxel-index units per world unit
    t0: np.ndarray  # (R,) float32: entry distance (world units)
    dt: np.ndarray  # (R,) float32: segment length, (t1 - t0) / n (0 for rays that miss)
    n: np.ndarray  # (R,) int32: samples on the ray (0 for rays that miss)


@dataclass
class Scene:
    volume: np.ndarray  # (nz, ny, nx) float32
    target: np.ndarray  # (views, H, W, 4) float32
    tf: np.ndarray  # (points, 5) float32: density, r, g, b, extinction (densities ascending)
    background: np.ndarray  # (3,) float32
    min_transmittance: float
    step: float  # world units
    loss: str  # "mse": mean over every element of (image - target)^2
    rays: Rays
    views: int
    height: int
    width: int

    @property
    def max_samples(self) -> int:
        return int(self.rays.n.max()) if self.rays.n.size else 0

    @property
    def tf_parameters(self) -> np.ndarray:
        """The TF's parameters in ivr's gradient layout: (points, 4) [r, g, b, extinction]."""
        return self.tf[:, 1:5].copy()


def _normalize(v):
    return v / np.linalg.norm(v)


def camera_rays(scene_json: dict, shape) -> Rays:
    """Perspective rays exactly as kernels/camera.cl and bench/native_marcher.cpp set them up."""
    nz, ny, nx = shape
    bmin = np.asarray(scene_json["box_min"], np.float64)
    bmax = np.asarray(scene_json["box_max"], np.float64)
    h = (bmax - bmin) / np.array([nx, ny, nz], np.float64)
    step = float(scene_json["step"])
    f32 = np.float32
    u0s, dus, t0s, dts, ns = [], [], [], [], []
    for cam in scene_json["cameras"]:
        eye, target, up = (np.asarray(cam[k], np.float64) for k in ("eye", "target", "up"))
        W, H = int(cam["width"]), int(cam["height"])
        fwd = _normalize(target - eye)
        right = _normalize(np.cross(fwd, up))
        upv = np.cross(right, fwd)
        half = math.tan(0.5 * float(cam["fov_y"]) * math.pi / 180.0)
        f, r, u = fwd.astype(f32), (half * W / H * right).astype(f32), (half * upv).astype(f32)
        xs = (f32(2) * (np.arange(W, dtype=f32) + f32(0.5)) / f32(W) - f32(1)).astype(f32)
        ys = (f32(1) - f32(2) * (np.arange(H, dtype=f32) + f32(0.5)) / f32(H)).astype(f32)
        sx, sy = np.meshgrid(xs, ys)  # (H, W)
        d = f[None, None, :] + sx[..., None] * r + sy[..., None] * u
        d = (d / np.sqrt((d * d).sum(-1, keepdims=True))).astype(f32).reshape(-1, 3)
        e = eye.astype(f32)
        t0 = np.zeros(len(d), f32)
        t1 = np.full(len(d), np.inf, f32)
        for a in range(3):
            lo, hi = f32(bmin[a]), f32(bmax[a])
            da = d[:, a]
            nz_mask = da != 0
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = f32(1) / np.where(nz_mask, da, f32(1))
                ta, tb = (lo - e[a]) * inv, (hi - e[a]) * inv
            t0 = np.where(nz_mask, np.maximum(t0, np.minimum(ta, tb)), t0)
            t1 = np.where(nz_mask, np.minimum(t1, np.maximum(ta, tb)), t1)
            outside = (~nz_mask) & ((e[a] < lo) | (e[a] > hi))
            t1 = np.where(outside, f32(-1), t1)
        hit = t0 < t1
        length = np.where(hit, t1 - t0, f32(0)).astype(f32)
        n = np.where(hit, np.maximum(1, np.ceil(length / f32(step))), 0).astype(np.int32)
        dt = np.where(hit, length / np.maximum(n, 1).astype(f32), f32(0)).astype(f32)
        inv_h = (1.0 / h).astype(f32)
        u0 = ((e - bmin.astype(f32)) * inv_h - f32(0.5)).astype(f32)
        u0s.append(np.broadcast_to(u0, d.shape).copy())
        dus.append((d * inv_h).astype(f32))
        t0s.append(np.where(hit, t0, f32(0)).astype(f32))
        dts.append(dt)
        ns.append(n)
    cat = np.concatenate
    return Rays(cat(u0s), cat(dus), cat(t0s), cat(dts), cat(ns))


def load_scene(case_dir: str) -> Scene:
    with open(os.path.join(case_dir, "scene.json")) as f:
        s = json.load(f)
    if s.get("format") != SCENE_FORMAT:
        raise ValueError(f"{case_dir}/scene.json: format {s.get('format')!r}, expected {SCENE_FORMAT}")
    volume = np.load(os.path.join(case_dir, s["volume"])).astype(np.float32)
    target = np.load(os.path.join(case_dir, s["target"])).astype(np.float32)
    cams = s["cameras"]
    views, H, W = len(cams), int(cams[0]["height"]), int(cams[0]["width"])
    if target.shape != (views, H, W, 4):
        raise ValueError(f"{case_dir}/target.npy: shape {target.shape}, expected {(views, H, W, 4)}")
    return Scene(
        volume=volume,
        target=target,
        tf=np.asarray(s["tf"], np.float32),
        background=np.asarray(s["background"], np.float32),
        min_transmittance=float(s["min_transmittance"]),
        step=float(s["step"]),
        loss=s.get("loss", "mse"),
        rays=camera_rays(s, volume.shape),
        views=views,
        height=H,
        width=W,
    )
