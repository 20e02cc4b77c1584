"""test_drjit.py — checks drjit_march.py against an independent float64 numpy march of tiny scenes.

render within atol 1e-5 + rtol 1e-4; grad (both reverse-mode variants) and tf_forward against
central differences of the numpy march within 2e-5·max|g| + 1e-3 relative (they agree to ~1e-6
of max|g|); run.py end to end once. Run: VENV/bin/python -m pytest bench/baselines/test_drjit.py
"""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("drjit")

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import drjit as dr  # noqa: E402
import drjit_march  # noqa: E402
from common import load_scene, outputs_to_numpy  # noqa: E402

TF = [
    [0.15, 0.9, 0.2, 0.1, 1.5],
    [0.35, 0.1, 0.3, 0.9, 4.0],
    [0.6, 0.9, 0.6, 0.2, 9.0],
    [0.85, 1.0, 1.0, 0.9, 14.0],
]


def write_case(path, min_transmittance, seed=7):
    rng = np.random.default_rng(seed)
    n = 6
    volume = rng.random((n, n, n), dtype=np.float32)
    W, H = 8, 6
    cams = [
        {"eye": [1.1, 0.8, 1.5], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 38.0, "width": W, "height": H},
        {"eye": [-1.6, -0.4, 0.7], "target": [0.05, 0, 0], "up": [0, 1, 0], "fov_y": 45.0, "width": W, "height": H},
    ]
    target = rng.random((len(cams), H, W, 4), dtype=np.float32)
    os.makedirs(path, exist_ok=True)
    np.save(os.path.join(path, "volume.npy"), volume)
    np.save(os.path.join(path, "target.npy"), target)
    doc = {
        "format": "ivr-bench-scene/1",
        "volume": "volume.npy",
        "target": "target.npy",
        "tf": TF,
        "background": [0.05, 0.1, 0.15],
        "min_transmittance": min_transmittance,
        "step": 0.5 / n,
        "loss": "mse",
        "box_min": [-0.5, -0.5, -0.5],
        "box_max": [0.5, 0.5, 0.5],
        "cameras": cams,
    }
    with open(os.path.join(path, "scene.json"), "w") as f:
        json.dump(doc, f)
    return path


# -- an independent float64 march ------------------------------------------------------------


def np_tf(tf, d):
    dens, vals = tf[:, 0], tf[:, 1:5]
    out = np.broadcast_to(vals[0], d.shape + (4,)).copy()
    for k in range(len(dens) - 1):
        lo, hi = dens[k], dens[k + 1]
        sel = (d > dens[0]) & (d >= lo) & (d < hi)
        if hi > lo and sel.any():
            w = ((d[sel] - lo) / (hi - lo))[:, None]
            out[sel] = (1 - w) * vals[k] + w * vals[k + 1]
    out[d >= dens[-1]] = vals[-1]
    return out


def np_trilinear(vol, u):
    nz, ny, nx = vol.shape
    idx, frac = [], []
    for a, size in enumerate((nx, ny, nz)):
        c = np.clip(u[:, a], 0, size - 1)
        c0 = np.floor(c)
        frac.append(c - c0)
        i0 = c0.astype(np.int64)
        idx.append((i0, np.minimum(i0 + 1, size - 1)))
    (x0, x1), (y0, y1), (z0, z1) = idx
    fx, fy, fz = frac
    out = 0
    for zi, wz in ((z0, 1 - fz), (z1, fz)):
        for yi, wy in ((y0, 1 - fy), (y1, fy)):
            for xi, wx in ((x0, 1 - fx), (x1, fx)):
                out = out + wz * wy * wx * vol[zi, yi, xi]
    return out


def np_render(scene, volume=None, tf=None):
    vol = np.asarray(scene.volume if volume is None else volume, np.float64)
    tf = np.asarray(scene.tf if tf is None else tf, np.float64)
    r = scene.rays
    u0, du, t0, dt = (np.asarray(x, np.float64) for x in (r.u0, r.du, r.t0, r.dt))
    R = len(r.n)
    T, C = np.ones(R), np.zeros((R, 3))
    for i in range(int(r.n.max())):
        act = (i < r.n) & (T >= scene.min_transmittance)
        t = t0 + (i + 0.5) * dt
        vals = np_tf(tf, np_trilinear(vol, u0 + t[:, None] * du))
        a = np.exp(-vals[:, 3] * dt)
        C = np.where(act[:, None], C + (T * (1 - a))[:, None] * vals[:, :3], C)
        T = np.where(act, T * a, T)
    px = np.concatenate([C + T[:, None] * np.asarray(scene.background, np.float64), (1 - T)[:, None]], 1)
    return px.reshape(scene.views, scene.height, scene.width, 4)


def np_loss(scene, **kw):
    return float(np.mean((np_render(scene, **kw) - scene.target.astype(np.float64)) ** 2))


def central(f, x, eps):
    """Central differences in float64. The callers' tiny eps (1e-6) keeps every perturbed sample's
    density on the same TF segment and every early-termination decision unchanged, where the
    march is not differentiable."""
    g = np.zeros(x.shape)
    for idx in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[idx] += eps
        xm[idx] -= eps
        g[idx] = (f(xp) - f(xm)) / (2 * eps)
    return g


# -- tests -----------------------------------------------------------------------------------

MIN_T = (0.0, 0.3)


@pytest.fixture(scope="module", params=MIN_T, ids=lambda m: f"minT{m}")
def scene(request, tmp_path_factory):
    path = write_case(str(tmp_path_factory.mktemp(f"case{request.param}")), request.param)
    s = load_scene(path)
    assert (s.rays.n == 0).any() and (s.rays.n > 0).any()  # some rays miss, most hit
    return s


@pytest.fixture(scope="module", autouse=True)
def _version():
    drjit_march.version(2)


def test_early_termination_is_exercised(scene):
    T = 1 - np_render(scene)[..., 3]
    if scene.min_transmittance > 0:
        T_all = 1 - np_render(dataclasses.replace(scene, min_transmittance=0.0))[..., 3]
        stopped = T != T_all
        assert stopped.sum() >= 5  # rays that stop early
        assert (T[stopped] < scene.min_transmittance).all()
    else:
        assert (T < 0.3).any()


def test_render(scene):
    out = outputs_to_numpy(drjit_march.prepare("render", scene)())
    assert out["image"].shape == (scene.views, scene.height, scene.width, 4)
    assert out["image"].dtype == np.float32
    ref = np_render(scene)
    np.testing.assert_allclose(out["image"], ref, atol=1e-5, rtol=1e-4)
    miss = (scene.rays.n == 0).reshape(scene.views, scene.height, scene.width)
    np.testing.assert_array_equal(out["image"][miss][:, :3], np.broadcast_to(scene.background, (miss.sum(), 3)))
    assert (out["image"][miss][:, 3] == 0).all()
    # A second call (cached kernel) gives the same image.
    again = outputs_to_numpy(drjit_march.prepare("render", scene)())
    np.testing.assert_array_equal(again["image"], out["image"])


@pytest.fixture(scope="module")
def fd_volume_grad(scene):
    vol = scene.volume.astype(np.float64)
    return central(lambda v: np_loss(scene, volume=v), vol, 1e-6)


@pytest.mark.parametrize("reverse", ["replay", "loop"])
def test_grad(scene, fd_volume_grad, reverse, monkeypatch):
    monkeypatch.setattr(drjit_march, "REVERSE", reverse)
    call = drjit_march.prepare("grad", scene)
    out = outputs_to_numpy(call())
    assert out["grad"].shape == scene.volume.shape and out["grad"].dtype == np.float32
    assert abs(out["loss"] - np_loss(scene)) <= 1e-6 + 1e-5 * np_loss(scene)
    g, ref = out["grad"], fd_volume_grad
    scale = np.abs(ref).max()
    assert scale > 0
    np.testing.assert_allclose(g, ref, atol=2e-5 * scale, rtol=1e-3)
    # Repeated calls do not accumulate gradients.
    np.testing.assert_allclose(outputs_to_numpy(call())["grad"], g, atol=1e-7 * scale, rtol=1e-5)


def test_tf_forward(scene):
    call = drjit_march.prepare("tf_forward", scene)
    out = outputs_to_numpy(call())
    assert out["tf_grad"].shape == (len(scene.tf), 4)
    assert abs(out["loss"] - np_loss(scene)) <= 1e-6 + 1e-5 * np_loss(scene)
    tf0 = scene.tf.astype(np.float64)

    def f(params):
        tf = tf0.copy()
        tf[:, 1:5] = params
        return np_loss(scene, tf=tf)

    ref = central(f, tf0[:, 1:5].copy(), 1e-6)
    scale = np.abs(ref).max()
    np.testing.assert_allclose(out["tf_grad"], ref, atol=2e-5 * scale, rtol=1e-3)
    np.testing.assert_allclose(outputs_to_numpy(call())["tf_grad"], out["tf_grad"],
                               atol=1e-7 * scale, rtol=1e-5)


def test_run_end_to_end(scene, tmp_path):
    case = str(tmp_path / "case")
    write_case(case, scene.min_transmittance)
    out = tmp_path / "result.json"
    here = os.path.dirname(os.path.abspath(__file__))
    p = subprocess.run([sys.executable, os.path.join(here, "run.py"), "--framework", "drjit",
                        "--task", "grad", "--case", case, "--out", str(out), "--budget", "0",
                        "--min-repeats", "2", "--threads", "2"], capture_output=True, text=True)
    assert p.returncode == 0, p.stdout + p.stderr
    doc = json.loads(out.read_text())
    assert doc["ok"] and doc["available"] and "LLVM backend" in doc["version"], doc
    assert abs(doc["loss"] - np_loss(scene)) <= 1e-6 + 1e-5 * np_loss(scene)
    grad = np.load(os.path.join(case, doc["outputs"]["grad"]))
    assert grad.shape == scene.volume.shape


@pytest.mark.parametrize("task", ["render", "grad", "tf_forward"])
def test_call_finishes_the_device_work(scene, task):
    """Every kernel of a task runs inside call() (dr.eval + dr.sync_thread at its end): turning its
    outputs into numpy afterwards, as run.py does after the timed calls, only copies (Memcpy;
    none at all on the LLVM backend for arrays numpy can view)."""
    call = drjit_march.prepare(task, scene)
    call()  # compile
    history = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        out = call()
        during = dr.kernel_history()
        outputs_to_numpy(out)
        after = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, history)
    assert any(k["type"] == dr.KernelType.JIT for k in during)
    assert all(k["type"] == dr.KernelType.Memcpy for k in after), after


def test_gpu_backend_unavailable_here_or_cuda():
    """version(threads, "gpu") selects drjit.cuda.ad, or says why it cannot (DeviceUnavailable);
    either way the CPU types are back after version(threads, "cpu")."""
    from common import DeviceUnavailable

    try:
        text = drjit_march.version(0, "gpu")
        assert "CUDA" in text and drjit_march.Float.__module__ == "drjit.cuda.ad"
    except DeviceUnavailable as e:
        assert "CUDA" in str(e)
    finally:
        drjit_march.version(2, "cpu")
    assert drjit_march.Float.__module__ == "drjit.llvm.ad"
    assert drjit_march.BACKEND == dr.JitBackend.LLVM
