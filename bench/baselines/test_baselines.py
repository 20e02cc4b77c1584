"""test_baselines.py — checks every installed baseline against reference.py on tiny scenes (pytest).

    .venv-bench/bin/python -m pytest bench/baselines

Each framework's render is compared with the float64 reference, its gradients with central finite
differences of it; frameworks that are not installed are skipped. run.py is run end to end once,
and common.py's rays are checked against a one-pixel computation written out here.
"""
from __future__ import annotations

import importlib
import importlib.util
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import common  # noqa: E402
import reference  # noqa: E402

FRAMEWORKS = ("jax", "drjit", "torch")
# torch.func's first use warns about torch.jit.script's deprecation (torch's own code, not ours).
pytestmark = pytest.mark.filterwarnings("ignore:.*torch.jit.script.*:FutureWarning")
# A 4-point TF; densities of the random volume fall below the first and above the last point too.
TF = [[0.15, 0.9, 0.2, 0.1, 0.5],
      [0.40, 0.2, 0.8, 0.3, 2.0],
      [0.65, 0.1, 0.3, 0.9, 4.0],
      [0.85, 1.0, 1.0, 0.6, 1.0]]
CAMERAS = [  # 8×6 each; the first also sees past the box, so some rays miss (n = 0)
    {"eye": [1.2, 0.7, 1.6], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_y": 50.0,
     "width": 8, "height": 6},
    {"eye": [-0.3, -1.4, 0.9], "target": [0.05, 0.0, -0.02], "up": [0.0, 0.0, 1.0], "fov_y": 35.0,
     "width": 8, "height": 6},
]


def make_case(directory, *, min_transmittance: float, seed: int = 7, step: float = 0.5 / 6) -> str:
    """Writes a case directory as ivr-bench does: scene.json, volume.npy, target.npy."""
    os.makedirs(directory, exist_ok=True)
    rng = np.random.default_rng(seed)
    volume = rng.random((6, 6, 6), dtype=np.float32)
    target = rng.random((len(CAMERAS), 6, 8, 4), dtype=np.float32)
    np.save(os.path.join(directory, "volume.npy"), volume)
    np.save(os.path.join(directory, "target.npy"), target)
    scene = {
        "format": common.SCENE_FORMAT, "volume": "volume.npy", "target": "target.npy",
        "tf": TF, "background": [0.1, 0.2, 0.3], "min_transmittance": min_transmittance,
        "step": step, "loss": "mse", "box_min": [-0.5, -0.5, -0.5], "box_max": [0.5, 0.5, 0.5],
        "cameras": CAMERAS,
    }
    with open(os.path.join(directory, "scene.json"), "w") as f:
        json.dump(scene, f, indent=1)
    return str(directory)


@pytest.fixture(scope="module", params=[0.0, 0.3], ids=["no-termination", "termination"])
def scene(request, tmp_path_factory):
    case = make_case(tmp_path_factory.mktemp("case"), min_transmittance=request.param)
    return common.load_scene(case)


@pytest.fixture(scope="module")
def expected(scene):
    """The reference's image, loss and finite-difference gradients (computed once per scene)."""
    return {
        "image": reference.render(scene),
        "loss": reference.loss(scene),
        "grad": reference.grad_volume_fd(scene),
        "tf_grad": reference.grad_tf_fd(scene),
    }


def _module(framework):
    pytest.importorskip(framework)
    module = importlib.import_module(f"{framework}_march")
    module.version(0)
    return module


def _close(actual, wanted, atol, rtol, what):
    actual, wanted = np.asarray(actual, np.float64), np.asarray(wanted, np.float64)
    assert actual.shape == wanted.shape, f"{what}: shape {actual.shape}, expected {wanted.shape}"
    err = np.abs(actual - wanted)
    bad = err > atol + rtol * np.abs(wanted)
    assert not bad.any(), (f"{what}: {bad.sum()} of {bad.size} off, worst {err.max():.3g} "
                           f"(atol {atol:.3g}, rtol {rtol:.3g})")


def test_scene_exercises_the_march(scene, expected):
    """The tiny scenes cover what the tests are meant to: misses, clamped TF ends, termination."""
    n = scene.rays.n
    assert (n == 0).any() and (n > 0).sum() > 40
    assert scene.max_samples >= 10
    d = scene.volume
    assert (d < TF[0][0]).any() and (d > TF[-1][0]).any()
    alpha = expected["image"][..., 3]
    if scene.min_transmittance > 0:  # some rays end early: their alpha reaches 1 - min_T
        assert (alpha > 1 - scene.min_transmittance).any()


@pytest.mark.parametrize("framework", FRAMEWORKS)
def test_render(framework, scene, expected):
    out = common.outputs_to_numpy(_module(framework).prepare("render", scene)())
    assert out["image"].dtype == np.float32
    _close(out["image"], expected["image"], 1e-5, 1e-4, f"{framework} render")


@pytest.mark.parametrize("framework", FRAMEWORKS)
def test_grad(framework, scene, expected):
    out = common.outputs_to_numpy(_module(framework).prepare("grad", scene)())
    assert out["grad"].dtype == np.float32 and out["grad"].shape == scene.volume.shape
    assert math.isclose(float(out["loss"]), expected["loss"], rel_tol=1e-5)
    g = expected["grad"]
    assert np.abs(g).max() > 1e-4  # the check means something
    _close(out["grad"], g, 2e-5 * np.abs(g).max(), 1e-3, f"{framework} grad")


@pytest.mark.parametrize("framework", FRAMEWORKS)
def test_tf_forward(framework, scene, expected):
    module = _module(framework)
    try:
        out = common.outputs_to_numpy(module.prepare("tf_forward", scene)())
    except NotImplementedError as e:
        pytest.skip(f"{framework}: {e}")
    assert out["tf_grad"].shape == (len(TF), 4)
    assert math.isclose(float(out["loss"]), expected["loss"], rel_tol=1e-5)
    g = expected["tf_grad"]
    _close(out["tf_grad"], g, 2e-5 * np.abs(g).max(), 1e-3, f"{framework} tf_forward")


def test_rays_one_pixel(tmp_path):
    """common.camera_rays against a direct float64 computation for one pixel of the second view."""
    scene = common.load_scene(make_case(tmp_path, min_transmittance=0.0))
    cam, view, y, x = CAMERAS[1], 1, 4, 5
    W, H = cam["width"], cam["height"]
    eye, tgt, up = (np.array(cam[k], float) for k in ("eye", "target", "up"))
    fwd = (tgt - eye) / np.linalg.norm(tgt - eye)
    right = np.cross(fwd, up) / np.linalg.norm(np.cross(fwd, up))
    true_up = np.cross(right, fwd)
    half = math.tan(math.radians(cam["fov_y"]) / 2)
    sx, sy = (2 * (x + 0.5) / W - 1) * half * W / H, (1 - 2 * (y + 0.5) / H) * half
    d = fwd + sx * right + sy * true_up
    d /= np.linalg.norm(d)
    # The segment inside the box [-0.5, 0.5]^3 (slabs), eye outside the box.
    ta, tb = (-0.5 - eye) / d, (0.5 - eye) / d
    t_in, t_out = np.minimum(ta, tb).max(), np.maximum(ta, tb).min()
    assert t_in < t_out
    n = math.ceil((t_out - t_in) / (0.5 / 6))
    i = (view * H + y) * W + x
    r = scene.rays
    voxel = 1.0 / 6
    assert r.n[i] == n
    assert math.isclose(r.t0[i], t_in, rel_tol=1e-5)
    assert math.isclose(r.dt[i], (t_out - t_in) / n, rel_tol=1e-5)
    np.testing.assert_allclose(r.u0[i], (eye + 0.5) / voxel - 0.5, rtol=1e-6)
    np.testing.assert_allclose(r.du[i], d / voxel, rtol=1e-5)
    # The first sample's voxel-index position is the world point's, in voxel-centre coordinates.
    p = eye + (t_in + 0.5 * r.dt[i]) * d
    np.testing.assert_allclose(r.u0[i] + (r.t0[i] + 0.5 * r.dt[i]) * r.du[i],
                               (p + 0.5) / voxel - 0.5, atol=1e-4)


def _run(args, env=None):
    return subprocess.run([sys.executable, os.path.join(HERE, "run.py"), *args],
                          capture_output=True, text=True, env=env, timeout=600)


def test_run_end_to_end(tmp_path):
    pytest.importorskip("jax")
    case = make_case(tmp_path / "case", min_transmittance=0.3)
    out = tmp_path / "result.json"
    p = _run(["--framework", "jax", "--task", "grad", "--case", case, "--out", str(out),
              "--budget", "0.2", "--threads", "1"])
    assert p.returncode == 0, p.stdout + p.stderr
    doc = json.loads(out.read_text())
    assert doc["available"] is True and doc["ok"] is True, doc
    assert doc["framework"] == "jax" and doc["task"] == "grad" and "jax" in doc["version"]
    assert len(doc["times_s"]) >= 3 and doc["median_s"] > 0 and doc["first_call_s"] > 0
    assert doc["peak_increase_bytes"] >= 0 and doc["march_steps"] > 0
    scene = common.load_scene(case)
    assert math.isclose(doc["loss"], reference.loss(scene), rel_tol=1e-5)
    grad = np.load(os.path.join(case, doc["outputs"]["grad"]))
    assert grad.shape == scene.volume.shape and grad.dtype == np.float32


def test_run_unavailable_framework(tmp_path):
    """A framework that cannot be imported is reported as unavailable (exit 0), not as a failure:
    a stand-in `torch` package that raises ImportError is put first on the path."""
    shadow = tmp_path / "shadow" / "torch"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text("raise ImportError('torch hidden by the test')\n")
    case = make_case(tmp_path / "case", min_transmittance=0.0)
    out = tmp_path / "result.json"
    env = dict(os.environ, PYTHONPATH=str(shadow.parent))
    p = _run(["--framework", "torch", "--task", "render", "--case", case, "--out", str(out)], env)
    assert p.returncode == 0, p.stdout + p.stderr
    doc = json.loads(out.read_text())
    assert doc["available"] is False and "not installed" in doc["note"], doc


# -- devices (--device cpu|gpu) ----------------------------------------------------------------

def _run_case(tmp_path, name, framework, task, *extra):
    """run.py on a fresh copy of the termination case; returns (result JSON, case directory)."""
    case = make_case(tmp_path / name, min_transmittance=0.3)
    out = tmp_path / f"{name}.json"
    p = _run(["--framework", framework, "--task", task, "--case", case, "--out", str(out),
              "--budget", "0", "--min-repeats", "1", "--threads", "1", *extra])
    assert p.returncode == 0, p.stdout + p.stderr
    return json.loads(out.read_text()), case


def _outputs(doc, case):
    return {name: np.load(os.path.join(case, file)) for name, file in doc["outputs"].items()}


@pytest.mark.parametrize("task", ["render", "grad"])
@pytest.mark.parametrize("framework", FRAMEWORKS)
def test_run_device_cpu_is_the_default(framework, task, tmp_path):
    """--device cpu is what run.py did before the option existed: same outputs as no --device."""
    pytest.importorskip(framework)
    default, case_d = _run_case(tmp_path, "default", framework, task)
    cpu, case_c = _run_case(tmp_path, "cpu", framework, task, "--device", "cpu")
    for doc in (default, cpu):
        assert doc["available"] and doc["ok"], doc
        assert doc["device"] == "cpu" and doc["device_name"], doc
        assert not any(k.startswith("device_peak") for k in doc), doc  # GPU-only fields
    out_d, out_c = _outputs(default, case_d), _outputs(cpu, case_c)
    assert out_d.keys() == out_c.keys() and out_d
    for name in out_d:
        assert out_d[name].dtype == out_c[name].dtype == np.float32
        if task == "render":  # no reductions: bit for bit
            np.testing.assert_array_equal(out_c[name], out_d[name])
        else:  # multithreaded scatter-adds may sum in another order
            np.testing.assert_allclose(out_c[name], out_d[name], rtol=1e-5,
                                       atol=1e-6 * np.abs(out_d[name]).max())
    if task == "grad":
        assert math.isclose(cpu["loss"], default["loss"], rel_tol=1e-6)


@pytest.mark.parametrize("framework", FRAMEWORKS)
def test_run_device_gpu(framework, tmp_path):
    """--device gpu: without a usable GPU (this project's machines), every framework reports
    "available": false with a note and exit 0; with one, every task runs on it and matches the
    reference like the CPU tests do."""
    doc, case = _run_case(tmp_path, "render", framework, "render", "--device", "gpu")
    assert doc["device"] == "gpu", doc
    if not doc["available"]:
        assert doc["note"].startswith(f"{framework} has no GPU here: ") or (
            "not installed" in doc["note"]), doc
        assert "ok" not in doc and "outputs" not in doc, doc
        return
    # A GPU machine: the outputs were computed there; compare them with the reference.
    assert doc["ok"], doc
    assert doc["device_name"], doc
    assert "device_peak_bytes" in doc or "device_memory_error" in doc, doc
    scene = common.load_scene(case)
    _close(_outputs(doc, case)["image"], reference.render(scene), 1e-5, 1e-4,
           f"{framework} gpu render")
    doc, case = _run_case(tmp_path, "grad", framework, "grad", "--device", "gpu")
    assert doc["ok"], doc
    assert math.isclose(doc["loss"], reference.loss(scene), rel_tol=1e-5)
    g = reference.grad_volume_fd(scene)
    _close(_outputs(doc, case)["grad"], g, 2e-5 * np.abs(g).max(), 1e-3, f"{framework} gpu grad")
    doc, case = _run_case(tmp_path, "tf_forward", framework, "tf_forward", "--device", "gpu")
    if doc.get("ok"):
        g = reference.grad_tf_fd(scene)
        _close(_outputs(doc, case)["tf_grad"], g, 2e-5 * np.abs(g).max(), 1e-3,
               f"{framework} gpu tf_forward")
    else:
        assert "NotImplementedError" in doc.get("error", ""), doc


def test_to_numpy_plain_values():
    a = np.arange(6, dtype=np.float32).reshape(2, 3)
    assert common.to_numpy(a) is a
    s = common.to_numpy(0.25)
    assert s.ndim == 0 and float(s) == 0.25
    d = common.to_numpy(common.Deferred(lambda: a * 2))
    np.testing.assert_array_equal(d, a * 2)


def test_to_numpy_framework_arrays():
    """Each installed framework's arrays (and a torch tensor that requires grad, which np.asarray
    refuses) come back as numpy with their values, dtype and shape."""
    want = np.array([[0.5, -1.0, 2.0], [3.0, 4.5, 1e-3]], np.float32)
    arrays = {}
    if importlib.util.find_spec("jax"):
        _module("jax")
        import jax.numpy as jnp
        arrays["jax"] = jnp.asarray(want)
        arrays["jax scalar"] = jnp.float32(0.5)
    if importlib.util.find_spec("torch"):
        import torch
        arrays["torch"] = torch.from_numpy(want.copy()).requires_grad_(True) * 1.0
        arrays["torch scalar"] = torch.tensor(0.5)
    if importlib.util.find_spec("drjit"):
        import drjit_march
        flat = drjit_march.Float(want.ravel())
        arrays["drjit"] = common.Deferred(lambda: np.asarray(flat).reshape(2, 3))
        arrays["drjit raw"] = drjit_march.Float(want.ravel())
    if not arrays:
        pytest.skip("no framework installed")
    for name, value in arrays.items():
        got = common.to_numpy(value)
        assert isinstance(got, np.ndarray), name
        if "scalar" in name:
            assert got.ndim == 0 and float(got) == 0.5, name
        elif name == "drjit raw":
            np.testing.assert_array_equal(got, want.ravel())
        else:
            assert got.dtype == np.float32, name
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("framework", FRAMEWORKS)
def test_call_leaves_conversion_to_run(framework, scene):
    """call() returns the framework's own (device) arrays, computed; outputs_to_numpy turns them
    into numpy: float32 arrays and 0-d scalars."""
    call = _module(framework).prepare("grad", scene, "cpu")
    raw = call()
    assert set(raw) == {"loss", "grad"}
    assert not isinstance(raw["grad"], np.ndarray)  # converted by run.py after the timed calls
    out = common.outputs_to_numpy(raw)
    assert out["grad"].dtype == np.float32 and out["grad"].shape == scene.volume.shape
    assert out["loss"].ndim == 0
    assert math.isclose(float(out["loss"]), reference.loss(scene), rel_tol=1e-5)


def test_torch_gpu_path_keeps_every_tensor_on_the_device(scene, monkeypatch):
    """The GPU path with torch's "meta" device standing in for CUDA: a tensor made on the CPU
    anywhere in the march (a torch.zeros without device=) would fail with a device mismatch."""
    torch = pytest.importorskip("torch")
    module = _module("torch")
    monkeypatch.setattr(module, "_torch_device", lambda device: torch.device("meta"))
    for task in ("render", "grad", "tf_forward"):
        out = module.prepare(task, scene, "gpu")()
        assert all(v.device.type == "meta" for v in out.values()), (task, out)


def test_jax_gpu_path_places_everything_on_the_chosen_device(tmp_path):
    """The GPU path with a second host CPU device standing in for the GPU (XLA's
    --xla_force_host_platform_device_count, in a subprocess: it must be set before JAX starts):
    every output is committed to that device, with the device-0 values."""
    pytest.importorskip("jax")
    case = make_case(tmp_path / "case", min_transmittance=0.3)
    script = f"""
import sys
sys.path.insert(0, {HERE!r})
import numpy as np
import common, jax_march
jax_march.version(0)
import jax
second = jax.devices("cpu")[1]
cpu_device = jax_march._device
jax_march._device = lambda device: second if device == "gpu" else cpu_device(device)
scene = common.load_scene({case!r})
for task in ("render", "grad", "tf_forward"):
    out = jax_march.prepare(task, scene, "gpu")()
    ref = common.outputs_to_numpy(jax_march.prepare(task, scene, "cpu")())
    for name, value in out.items():
        assert value.devices() == {{second}} and value.committed, (task, name, value.devices())
        assert np.array_equal(common.to_numpy(value), ref[name]), (task, name)
print("ok")
"""
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2",
               JAX_PLATFORMS="cpu")
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env,
                       timeout=600)
    assert p.returncode == 0 and p.stdout.strip().endswith("ok"), p.stdout + p.stderr
