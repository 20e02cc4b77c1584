"""test_torch.py — ivr.torch: torch.autograd.gradcheck in float64 for every input of the
renderer (density, TF of each kind, background, camera; both optical models), for the projector
and its transpose; the planner's mode choice; a backward after a later forward; clear errors;
Adam through the renderer. Needs torch (Debian's python3-torch; skipped where missing)."""
import os
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")
import ivr  # noqa: E402
import ivr.torch as it  # noqa: E402

TRAIN = os.path.join(os.path.dirname(__file__), "../../../examples/python/torch_train.py")


def scene(model="emission_absorption", tf=None, width=4, height=3):
    """A small scene: one perspective view, early termination off (no sample count moves)."""
    if tf is None:
        tf = {"type": "piecewise_linear", "points": [
            {"density": 0.0, "color": [0.2, 0.4, 0.9], "extinction": 0.5},
            {"density": 1.5, "color": [1.0, 0.6, 0.2], "extinction": 6.0}]}
    return {"model": model, "tf": tf,
            "background": [0.1, 0.2, 0.3] if model != "absorption" else [1.0],
            "cameras": [{"eye": [1.2, 0.8, 1.5], "target": [0, 0, 0], "up": [0, 1, 0],
                         "fov_y": 40, "width": width, "height": height}],
            "integrator": {"scheme": "trapezoid", "step": 0.5, "min_transmittance": 0}}


def volume(shape=(3, 4, 5), seed=0):
    return torch.tensor(np.random.default_rng(seed).uniform(0.2, 0.8, shape),
                        dtype=torch.float64, requires_grad=True)


def check(f, *inputs, atol=1e-6, rtol=1e-4):
    assert torch.autograd.gradcheck(f, inputs, eps=1e-6, atol=atol, rtol=rtol)


@pytest.fixture(scope="module")
def ctx():
    with ivr.Context(precision="f64") as c:
        yield c


@pytest.mark.parametrize("model", ["emission_absorption", "absorption"])
def test_gradcheck_density_and_background(ctx, model):
    r = it.Renderer(scene(model), ctx, precision="f64")
    bg = torch.tensor([0.1, 0.2, 0.3] if model != "absorption" else [1.3], dtype=torch.float64,
                      requires_grad=True)
    check(lambda d: r(d), volume())
    check(lambda b: r(volume().detach(), background=b), bg)


@pytest.mark.parametrize("tf", [
    None,
    {"type": "gaussian", "gaussians": [
        {"mean": 0.4, "width": 0.2, "color": [0.9, 0.3, 0.2], "extinction": 3.0},
        {"mean": 0.7, "width": 0.15, "color": [0.2, 0.6, 1.0], "extinction": 5.0}]},
    {"type": "table", "range": [0.0, 1.0], "entries": [[0.1, 0.2, 0.9, 0.5], [0.9, 0.6, 0.2, 3.0],
                                                       [0.3, 0.8, 0.4, 1.5]]},
    {"type": "identity", "extinction_scale": 2.0, "color_scale": 0.7}],
    ids=["piecewise_linear", "gaussian", "table", "identity"])
def test_gradcheck_tf_of_every_kind(ctx, tf):
    s = scene(tf=tf)
    r = it.Renderer(s, ctx, precision="f64")
    p = r.tf_parameters().clone().requires_grad_(True)
    assert tuple(p.shape) == ((2,) if tf and tf["type"] == "identity" else
                              (len(next(v for k, v in (tf or s["tf"]).items()
                                         if isinstance(v, list) and k != "range")),
                               6 if tf and tf["type"] == "gaussian" else 4))
    d = volume().detach()
    check(lambda x: r(d, tf=x), p)


def test_gradcheck_camera_and_everything_at_once(ctx):
    r = it.Renderer(scene(), ctx, precision="f64")
    cam = r.camera_parameters().clone().requires_grad_(True)
    assert tuple(cam.shape) == (1, 7)
    check(lambda c: r(volume().detach(), camera=c), cam, atol=1e-5, rtol=1e-3)
    tf = r.tf_parameters().clone().requires_grad_(True)
    bg = torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64, requires_grad=True)
    check(lambda *x: r(*x), volume(), tf, bg, cam, atol=1e-5, rtol=1e-3)


def test_gradcheck_projector_and_its_transpose(ctx):
    s = {"model": "absorption", "tf": {"type": "identity", "extinction_scale": 1, "color_scale": 1},
         "cameras": [{"orbit": {"views": 3, "arc": 180, "projection": "orthographic",
                                "ortho_height": 1.0, "width": 5, "height": 4}}]}
    p = it.Projector(s, ctx, precision="f64", grid=(3, 4, 5))
    v = volume()
    lines = p(v)
    assert tuple(lines.shape) == (3, 4, 5, 1) and lines.dtype == torch.float64
    check(lambda x: it.project(p, x), v)
    q = torch.tensor(np.random.default_rng(3).normal(size=(3, 4, 5, 1)), requires_grad=True)
    check(lambda x: it.backproject(p, x), q)
    # <N v, q> = <v, N^T q>: the transpose is exact
    a = float((it.project(p, v) * q).sum())
    b = float((v * p.transpose(q)).sum())
    assert a == pytest.approx(b, rel=1e-12, abs=1e-12)


def test_planner_chooses_the_mode_by_parameter_count(ctx):
    r = it.Renderer(scene(width=8, height=8), ctx, precision="f64")
    d = volume((8, 8, 8))
    r(d).sum().backward()
    assert r.last_mode == "adjoint"  # 512 voxels
    tf = r.tf_parameters().clone().requires_grad_(True)
    r(d.detach(), tf=tf).sum().backward()
    assert r.last_mode == "forward"  # 8 TF parameters
    # the modes agree where both can run
    forced = it.Renderer(scene(width=8, height=8), ctx, precision="f64", mode="adjoint")
    tf2 = tf.detach().clone().requires_grad_(True)
    forced(d.detach(), tf=tf2).sum().backward()
    assert forced.last_mode == "adjoint"
    np.testing.assert_allclose(tf2.grad.numpy(), tf.grad.numpy(), rtol=1e-9, atol=1e-12)


def test_backward_after_a_later_forward_uses_its_own_inputs(ctx):
    r = it.Renderer(scene(), ctx, precision="f64")
    a, b = volume(seed=1), volume(seed=2)
    w1 = torch.rand(1, 3, 4, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    w2 = torch.rand(1, 3, 4, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(1))
    ((r(a) * w1).sum() + (r(b) * w2).sum()).backward()  # a's backward runs after b's forward
    a2, b2 = a.detach().clone().requires_grad_(True), b.detach().clone().requires_grad_(True)
    (r(a2) * w1).sum().backward()
    (r(b2) * w2).sum().backward()
    np.testing.assert_allclose(a.grad.numpy(), a2.grad.numpy(), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b.grad.numpy(), b2.grad.numpy(), rtol=1e-12, atol=1e-15)
    assert np.abs(a.grad.numpy() - b.grad.numpy()).max() > 0


def test_float32_tensors_in_and_out(ctx):
    with ivr.Context() as c32:
        r = it.Renderer(scene(), c32)
        d = torch.full((3, 4, 5), 0.4, requires_grad=True)
        img = r(d)
        assert img.dtype == torch.float32 and tuple(img.shape) == (1, 3, 4, 4)
        img.mean().backward()
        assert d.grad.dtype == torch.float32 and d.grad.shape == d.shape
        assert torch.isfinite(d.grad).all() and d.grad.abs().max() > 0


def test_errors_name_what_is_wrong(ctx):
    r = it.Renderer(scene(), ctx, precision="f64")
    d = volume().detach()
    with pytest.raises(ivr.Error, match=r"tf: a piecewise_linear TF of 2 rows takes shape \(2, 4\)"):
        r(d, tf=torch.zeros(3, 4, dtype=torch.float64))
    with pytest.raises(ivr.Error, match=r"background: \(3,\) RGB"):
        r(d, background=torch.zeros(2, dtype=torch.float64))
    with pytest.raises(ivr.Error, match="camera: shape \\(1, 7\\)"):
        r(d, camera=torch.zeros(2, 7, dtype=torch.float64))
    with pytest.raises(ivr.Error, match="floating-point"):
        r(torch.ones(3, 4, 5, dtype=torch.int32))
    with pytest.raises(ivr.Error, match="negative|>= 0"):
        r(-d)
    orbit = scene()
    orbit["cameras"] = [{"orbit": {"views": 2, "radius": 2, "width": 4, "height": 3}}]
    ro = it.Renderer(orbit, ctx, precision="f64")
    with pytest.raises(ivr.Error, match="listed one by one"):
        ro.camera_parameters()
    with pytest.raises(ivr.Error, match="has no volume; give grid"):
        it.Projector(scene("absorption"), ctx, precision="f64")
    with pytest.raises(ivr.Error, match="ivr.torch.Projector"):
        it.project(r, d)


def test_adam_through_the_renderer_lowers_the_loss(ctx):
    with ivr.Context() as c32:
        s = scene(width=12, height=12)
        s["cameras"] = [{"orbit": {"views": 4, "radius": 2.2, "fov_y": 35, "width": 12,
                                   "height": 12}}]
        r = it.Renderer(s, c32)
        true = torch.tensor(np.random.default_rng(4).uniform(0, 1, (8, 8, 8)), dtype=torch.float32)
        target = r(true).detach()
        v = torch.full((8, 8, 8), 0.5, requires_grad=True)
        opt = torch.optim.Adam([v], lr=0.05)
        losses = []
        for _ in range(15):
            opt.zero_grad()
            loss = ((r(v) - target) ** 2).mean()
            loss.backward()
            opt.step()
            with torch.no_grad():
                v.clamp_(min=0)
            losses.append(loss.item())
        assert losses[-1] < 0.2 * losses[0], losses


def test_training_example_runs_as_a_script():
    r = subprocess.run([sys.executable, TRAIN, "--size", "12", "--views", "6", "--resolution",
                        "16", "--iterations", "40"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "of its start" in r.stdout


def test_readme_pytorch_block_runs_after_the_python_one():
    """README.md's PyTorch block, run as it stands in the namespace its Python block leaves."""
    text = open(os.path.join(os.path.dirname(__file__), "../../../README.md")).read()

    def block(after):
        start = text.index("```python\n", text.index(after)) + len("```python\n")
        return text[start:text.index("```", start)]
    namespace = {}
    exec(compile(block("**Python**"), "README.md (Python)", "exec"), namespace)
    exec(compile(block("**PyTorch**"), "README.md (PyTorch)", "exec"), namespace)
    density, tf, renderer = namespace["density"], namespace["tf"], namespace["renderer"]
    assert density.grad is not None and density.grad.abs().max() > 0
    assert tf.grad is not None and tuple(tf.grad.shape) == (2, 4) and tf.grad.abs().max() > 0
    assert renderer.last_mode == "forward"


def test_zero_copy_gives_the_copied_paths_results(ctx):
    """On PoCL images and gradients are tensors over the device arrays and dL/dimage is read from
    the tensor's memory; the copying path (as on devices with memory of their own) gives the same
    image bits and the same gradients (to the order of the adjoint's atomic sums)."""
    a = it.Renderer(scene(), ctx, precision="f64")
    b = it.Renderer(scene(), ctx, precision="f64")
    assert a.zero_copy
    b.zero_copy = False
    results = []
    for r in (a, b):
        d = volume(seed=5)
        tf = r.tf_parameters().clone().requires_grad_(True)
        image = r(d, tf=tf)
        w = torch.linspace(-1, 1, image.numel(), dtype=torch.float64).reshape(image.shape)
        (image * w).sum().backward()
        results.append((image.detach().clone(), d.grad, tf.grad))
    check(lambda d: b(d), volume())  # the copying path keeps float64 too
    assert torch.equal(results[0][0], results[1][0])
    for x, y in zip(results[0][1:], results[1][1:]):
        np.testing.assert_allclose(x.numpy(), y.numpy(), rtol=1e-12, atol=1e-15)
    p = it.Projector({"model": "absorption", "tf": {"type": "identity"},
                      "cameras": [{"eye": [0, 0, 2], "width": 5, "height": 4}]}, ctx,
                     precision="f64", grid=(3, 4, 5))
    assert p.zero_copy
    v = volume()
    lines = it.project(p, v)
    q = p.session.project(v.detach().numpy()).numpy()
    np.testing.assert_array_equal(lines.detach().numpy(), q)
