"""test_ivr.py — the Python binding: render, grad and jacobian against the `ivr` CLI on the same
scene, errors as ivr.Error, and separate contexts on separate threads."""
import json
import os
import subprocess
import threading

import numpy as np
import pytest

import ivr

CLI = os.environ.get("IVR_CLI", "ivr")

# The scene the C API's tests use too (no volume: the tests pass one).
with open(os.path.join(os.path.dirname(__file__), "../../../tests/data/binding_scene.json")) as f:
    SCENE = json.load(f)


def volume():
    i = np.arange(4 * 5 * 6, dtype=np.float64)
    return (0.4 + 0.3 * np.sin(0.7 * i)).astype(np.float32).reshape(4, 5, 6)


@pytest.fixture(scope="module")
def ctx():
    with ivr.Context() as c:
        yield c


@pytest.fixture
def files(tmp_path):
    """The scene and volume as files, for the CLI."""
    np.save(tmp_path / "vol.npy", volume())
    scene = dict(SCENE, volume={"file": "vol.npy"})
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    return tmp_path


def cli(*args):
    r = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_devices_and_version():
    devs = ivr.devices()
    assert devs and {"name", "platform", "type", "fp64"} <= set(devs[0])
    assert len(ivr.version()) == 3


def test_render_equals_the_cli(ctx, files):
    image = ctx.render(SCENE, volume())
    assert image.shape == (1, 5, 6, 4) and image.dtype == np.float32
    cli("render", files / "scene.json", "-o", files / "out.npy")
    np.testing.assert_array_equal(image, np.load(files / "out.npy"))
    # uint8 volumes map to [0, 1] like the CLI's integer files
    as_bytes = (volume() * 255).round().astype(np.uint8)
    np.testing.assert_allclose(ctx.render(SCENE, as_bytes), image, atol=0.02)


def test_step_and_schemes_equal_the_cli(ctx, files):
    # The scene's own step; a tolerance's chosen step, as `ivr render --json` reports it.
    assert ctx.step(SCENE, volume()) == (SCENE["integrator"]["step"], 0.0)
    scene = dict(SCENE, integrator={"scheme": "preintegrated", "tolerance": 0.002})
    step, error = ctx.step(scene, volume())
    assert 0 < error <= 0.002 and step > 0
    with open(files / "tolerant.json", "w") as f:
        json.dump(dict(scene, volume={"file": "vol.npy"}), f)
    out = json.loads(cli("render", files / "tolerant.json", "-o", files / "t.npy", "--json"))
    assert out["scheme"] == "preintegrated" and out["step"] == step
    np.testing.assert_array_equal(ctx.render(scene, volume()), np.load(files / "t.npy"))
    with pytest.raises(ivr.Error, match="exact' integrates the absorption model only"):
        ctx.render(dict(SCENE, integrator={"scheme": "exact"}), volume())


def test_grad_equals_the_cli(ctx, files):
    target = np.full((1, 5, 6, 4), 0.25, dtype=np.float32)
    np.save(files / "target.npy", target)
    info = {}
    loss, grads = ctx.gradient(SCENE, volume(), target, wrt=("tf", "background", "voxels:3,7-9"),
                           mode="forward", info=info)
    assert info["mode"] == "forward"
    out = json.loads(cli("gradient", files / "scene.json", "--target", files / "target.npy",
                         "--wrt", "tf,background,voxels:3,7-9", "--mode", "forward",
                         "-o", files / "g", "--json"))
    assert loss == pytest.approx(out["loss"], rel=1e-12)
    for group in ("tf", "background", "voxels"):
        np.testing.assert_allclose(grads[group], np.load(files / f"g_{group}.npy"), rtol=1e-6,
                                   atol=1e-12)
    assert grads["tf"].shape == (2, 4) and grads["voxels"].shape == (4,)
    # density through the adjoint, and the same numbers as the C++ CLI's file
    loss2, g2 = ctx.gradient(SCENE, volume(), target, wrt="density", mode="adjoint")
    cli("gradient", files / "scene.json", "--target", files / "target.npy", "--wrt", "density",
        "--mode", "adjoint", "-o", files / "a")
    d = np.load(files / "a_density.npy")
    np.testing.assert_allclose(g2["density"], d, atol=1e-5 * np.abs(d).max())


def test_jacobian_equals_the_cli(ctx, files):
    J = ctx.jacobian(SCENE, volume(), wrt=("camera", "background"))
    assert J.shape == (1, 5, 6, 4, 10)
    cli("jacobian", files / "scene.json", "--wrt", "camera,background", "-o", files / "J.npy")
    np.testing.assert_allclose(J, np.load(files / "J.npy"), atol=1e-6 * np.abs(J).max())


def test_errors_raise_ivr_error(ctx):
    with pytest.raises(ivr.Error) as e:
        ctx.render(SCENE)  # no volume anywhere
    assert e.value.status == "IVR_ERROR_INVALID_ARGUMENT" and "no volume" in str(e.value)
    with pytest.raises(ivr.Error, match="unknown parameter group 'opacity'"):
        ctx.gradient(SCENE, volume(), np.zeros((1, 5, 6, 4), np.float32), wrt="opacity")
    with pytest.raises(ivr.Error, match="target has shape"):
        ctx.gradient(SCENE, volume(), np.zeros((5, 6, 3), np.float32))
    with pytest.raises(ivr.Error, match="dtype"):
        ctx.render(SCENE, volume().astype(np.int64))
    with pytest.raises(ivr.Error, match="shape"):
        ctx.render(SCENE, np.zeros((4, 5), np.float32))
    with pytest.raises(ivr.Error, match="mode must be one of"):
        ctx.gradient(SCENE, volume(), np.zeros((1, 5, 6, 4), np.float32), mode="sideways")
    with pytest.raises(ivr.Error) as e:
        ctx.render({"cameras": 3}, volume())
    assert e.value.status == "IVR_ERROR_INVALID_ARGUMENT"
    with pytest.raises(ivr.Error) as e:
        ivr.Context(device="no-such-device-xyz")
    assert e.value.status == "IVR_ERROR_NO_DEVICE"


def test_separate_contexts_on_separate_threads():
    want = ivr.Context().render(SCENE, volume())
    results, errors = [None] * 4, []

    def work(i):
        try:
            with ivr.Context() as c:
                for _ in range(3):
                    results[i] = c.render(SCENE, volume())
        except Exception as e:  # noqa: BLE001 — reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for r in results:
        np.testing.assert_array_equal(r, want)


def test_readme_snippet_runs():
    """The README's Python snippet, as it stands."""
    readme = (os.path.dirname(__file__) + "/../../../README.md")
    text = open(readme).read()
    start = text.index("```python\n", text.index("**Python**")) + len("```python\n")
    code = text[start:text.index("```", start)]
    exec(compile(code, "README.md", "exec"), {})


def test_loss_matches_numpy():
    rng = np.random.default_rng(3)
    a, b = rng.random((2, 5, 6, 4), dtype=np.float32), rng.random((2, 5, 6, 4), dtype=np.float32)
    assert ivr.loss(a, b) == pytest.approx(np.mean((a.astype(np.float64) - b) ** 2), rel=1e-12)
    assert ivr.loss(a, b, "l1") == pytest.approx(np.mean(np.abs(a.astype(np.float64) - b)),
                                                 rel=1e-12)
    with pytest.raises(ivr.Error, match="differ"):
        ivr.loss(a, b[0])


EXAMPLES = os.path.join(os.path.dirname(__file__), "../../../examples/python")


def test_example_runs():
    """examples/python/render.py exits 0 (the PyTorch examples: tests/test_torch*.py)."""
    import sys
    r = subprocess.run([sys.executable, os.path.join(EXAMPLES, "render.py")], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr


def test_load_volume(ctx, tmp_path):
    """Volumes read through the library as a scene reads them: a file, a raw file, synthetic."""
    v = volume()
    np.save(tmp_path / "v.npy", v)
    np.testing.assert_array_equal(ctx.load_volume(tmp_path / "v.npy"), v)
    (tmp_path / "v.raw").write_bytes((v * 255).astype(np.uint8).tobytes())
    raw = ctx.load_volume({"file": "v.raw", "dims": [6, 5, 4], "type": "uint8"},
                          base_dir=str(tmp_path))
    np.testing.assert_allclose(raw, (v * 255).astype(np.uint8) / 255.0, rtol=0, atol=1e-7)
    ml = ctx.load_volume({"synthetic": "marschner_lobb", "dims": [6, 7, 8]})
    assert ml.shape == (8, 7, 6) and 0 <= ml.min() and ml.max() <= 1
    with pytest.raises(ivr.Error, match="missing.npy"):
        ctx.load_volume(tmp_path / "missing.npy")


# Absorption tomography: 24 parallel-beam views on a half orbit about z, one pixel per voxel.
TOMO = {"model": "absorption", "tf": {"type": "identity", "extinction_scale": 1, "color_scale": 1},
        "cameras": [{"orbit": {"views": 24, "arc": 180, "projection": "orthographic",
                               "ortho_height": 1.0, "width": 16, "height": 16}}]}


def test_projector_pair_passes_the_dot_product_test(ctx):
    rng = np.random.default_rng(5)
    x = rng.uniform(-1, 1, (12, 10, 8)).astype(np.float32)  # (Z, Y, X): every axis differs
    y = rng.uniform(-1, 1, (24, 16, 16, 1)).astype(np.float32)
    nx = ctx.project(TOMO, x)
    assert nx.shape == (24, 16, 16, 1) and nx.dtype == np.float32
    nty = ctx.backproject(TOMO, y, grid=x.shape)
    assert nty.shape == x.shape and nty.dtype == np.float32
    a, b = np.dot(nx.ravel().astype(np.float64), y.ravel()), np.dot(x.ravel().astype(np.float64),
                                                                      nty.ravel())
    assert abs(a - b) <= 1e-5 * max(abs(a), abs(b))
    # (views, H, W) is accepted too; the module-level function gives the same numbers (up to the
    # order of the back-projection's atomic adds)
    np.testing.assert_allclose(ivr.backproject(TOMO, y[..., 0], grid=x.shape), nty, rtol=0,
                               atol=1e-5 * np.abs(nty).max())


def test_project_equals_the_cli(ctx, tmp_path):
    truth = ivr.phantom("shepp-logan", 16)
    np.save(tmp_path / "truth.npy", truth)
    (tmp_path / "scene.json").write_text(json.dumps(dict(TOMO, volume={"file": "truth.npy"})))
    cli("project", tmp_path / "scene.json", "-o", tmp_path / "P.npy")
    np.testing.assert_array_equal(ctx.project(TOMO, truth), np.load(tmp_path / "P.npy"))


def test_tomo_reconstructs_a_small_phantom(ctx):
    truth = ivr.phantom("shepp-logan", 16)
    assert truth.shape == (16, 16, 16) and truth.max() == pytest.approx(2.0)
    lines = ivr.project(TOMO, truth)
    seen, info = [], {}
    x, history = ctx.tomo(TOMO, lines, solver="cgls", iterations=20, grid=truth.shape,
                          progress=seen.append, info=info)
    assert x.shape == truth.shape and len(history) == 20 and seen == history
    assert info["stop_reason"] == "iterations"
    assert [h["iteration"] for h in history] == list(range(1, 21))
    assert history[-1]["residual"] < 0.1 * history[0]["residual"]
    assert np.linalg.norm(x - truth) / np.linalg.norm(truth) < 0.3
    # a progress function returning False stops the solver; nonneg keeps x >= 0
    x, history = ivr.tomo(TOMO, lines, iterations=20, nonneg=True, grid=truth.shape,
                          progress=lambda h: h["iteration"] < 3)
    assert len(history) == 3 and x.min() >= 0
    # intensities back to the same line integrals
    scene = dict(TOMO, background=0.5)
    back = ivr.lines_from_intensities(scene, 0.5 * np.exp(-lines))
    np.testing.assert_allclose(back, lines, atol=1e-5)


def test_tomo_errors_raise_ivr_error(ctx):
    lines = np.zeros((24, 16, 16, 1), np.float32)
    with pytest.raises(ivr.Error, match=r"lines have shape \(12, 16, 16, 1\)"):
        ctx.tomo(TOMO, lines[:12], grid=(16, 16, 16))
    bad = lines.copy()
    bad[1, 2, 3, 0] = np.nan
    with pytest.raises(ivr.Error, match="not finite") as e:
        ctx.backproject(TOMO, bad, grid=(16, 16, 16))
    assert e.value.status == "IVR_ERROR_INVALID_ARGUMENT"
    with pytest.raises(ivr.Error, match="solver must be one of"):
        ctx.tomo(TOMO, lines, solver="art", grid=(16, 16, 16))
    with pytest.raises(ivr.Error, match="tv must be >= 0"):
        ctx.tomo(TOMO, lines, tv=-1, grid=(16, 16, 16))
    with pytest.raises(ivr.Error, match="no volume"):
        ctx.backproject(TOMO, lines)  # no grid anywhere
    with pytest.raises(ivr.Error, match="unknown phantom|known"):
        ivr.phantom("cube", 8)

    def fails(_entry):
        raise KeyError("from the callback")
    with pytest.raises(KeyError, match="from the callback"):
        ctx.tomo(TOMO, lines + 1, iterations=5, grid=(16, 16, 16), progress=fails)


def test_out_of_core_render_equals_the_in_core_one(ctx, monkeypatch):
    # A volume split into bricks (forced, then chosen under a device-memory cap) renders the
    # in-core image to float32 rounding (docs/scaling.md).
    rng = np.random.default_rng(5)
    vol = rng.random((20, 17, 23), dtype=np.float32)
    scene = SCENE
    in_core = ctx.render(scene, vol)
    monkeypatch.setenv("IVR_VOLUME_BRICK", "4")
    np.testing.assert_allclose(ctx.render(scene, vol), in_core, rtol=0, atol=1e-5)
    monkeypatch.delenv("IVR_VOLUME_BRICK")
    monkeypatch.setenv("IVR_DEVICE_MEMORY_LIMIT", "24K")  # the volume alone is 30.5 KiB
    np.testing.assert_allclose(ctx.render(scene, vol), in_core, rtol=0, atol=1e-5)
    monkeypatch.setenv("IVR_DEVICE_MEMORY_LIMIT", "1K")
    with pytest.raises(ivr.Error, match="IVR_DEVICE_MEMORY_LIMIT"):
        ctx.render(scene, vol)
