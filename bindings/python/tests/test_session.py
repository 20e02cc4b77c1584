"""test_session.py — ivr.Session, ivr.DeviceArray and ivr.DensityOptimizer: resident renders,
gradients, Jacobians, projections and losses equal the one-shot Context calls on the same scene
(also after every setter), results stay valid, optimiser steps lower the loss, bad inputs raise
ivr.Error and leave the session as it was, and sessions work from several threads."""
import json
import os
import threading

import numpy as np
import pytest

import ivr

with open(os.path.join(os.path.dirname(__file__), "../../../tests/data/binding_scene.json")) as f:
    SCENE = json.load(f)  # emission-absorption, one 6x5 view, no volume


def volume():
    i = np.arange(4 * 5 * 6, dtype=np.float64)
    return (0.4 + 0.3 * np.sin(0.7 * i)).astype(np.float32).reshape(4, 5, 6)


# A 16^3 blob seen by two 16x16 views; the TF is 0 below density 0.05 (empty space to skip).
EA = {"model": "emission_absorption",
      "tf": {"type": "piecewise_linear", "points": [
          {"density": 0.05, "color": [0.2, 0.3, 0.9], "extinction": 0.0},
          {"density": 0.3, "color": [0.4, 0.5, 0.8], "extinction": 2.0},
          {"density": 0.9, "color": [1.0, 0.7, 0.2], "extinction": 6.0}]},
      "background": [0.1, 0.1, 0.1],
      "cameras": [{"orbit": {"views": 2, "arc": 180, "radius": 2.2, "fov_y": 35, "width": 16,
                             "height": 16}}],
      "integrator": {"scheme": "trapezoid", "step": 0.5}}

# Absorption tomography: 8 parallel-beam views of 16x16 rays.
TOMO = {"model": "absorption", "tf": {"type": "identity", "extinction_scale": 1, "color_scale": 1},
        "cameras": [{"orbit": {"views": 8, "arc": 180, "projection": "orthographic",
                               "ortho_height": 1.0, "width": 16, "height": 16}}]}


def blob(n=16, seed=0):
    z, y, x = np.mgrid[-1:1:n * 1j, -1:1:n * 1j, -1:1:n * 1j]
    r = np.sqrt(x**2 + (1.3 * y) ** 2 + (0.8 * z) ** 2)
    v = np.clip(1.0 - 1.6 * r, 0, None)
    v += 0.1 * np.random.default_rng(seed).random((n, n, n)) * (v > 0)  # the corners stay empty
    return v.astype(np.float32)


def close(actual, expected, rtol=1e-5, atol_scale=1e-5):
    """Equal up to rtol plus an absolute part scaled by the largest |expected|."""
    expected = np.asarray(expected, dtype=np.float64)
    atol = atol_scale * max(float(np.abs(expected).max(initial=0)), 1e-30)
    np.testing.assert_allclose(np.asarray(actual, dtype=np.float64), expected, rtol=rtol,
                               atol=atol)


@pytest.fixture(scope="module")
def ctx():
    with ivr.Context() as c:
        yield c


@pytest.fixture(scope="module")
def other_ctx():
    with ivr.Context() as c:
        yield c


def test_device_array_basics(ctx):
    a = ivr.DeviceArray(ctx, (2, 3))
    assert a.shape == (2, 3) and a.dtype == np.float32 and a.size == 6 and a.ndim == 2
    assert repr(a) == "ivr.DeviceArray(shape=(2, 3), dtype=float32)"
    np.testing.assert_array_equal(a.numpy(), np.zeros((2, 3), np.float32))
    values = np.arange(6, dtype=np.float64).reshape(3, 2) / 7  # any shape of the same size
    a.upload(values).wait()
    np.testing.assert_array_equal(np.asarray(a), (values.reshape(2, 3)).astype(np.float32))
    b = ivr.DeviceArray.from_numpy(ctx, values)
    assert b.dtype == np.float64 and b.shape == (3, 2)
    np.testing.assert_array_equal(b.numpy(), values)  # float64 kept bit for bit
    assert float(ivr.DeviceArray.from_numpy(ctx, [2.5])) == 2.5
    assert ivr.DeviceArray.from_numpy(ctx, np.float32([[0.25]])).item() == 0.25
    with pytest.raises(ivr.Error, match=r"upload: 5 values .* shape \(2, 3\)"):
        a.upload(np.zeros(5, np.float32))
    with pytest.raises(ivr.Error, match="float32 or float64, got int32"):
        a.upload(np.zeros(6, np.int32))
    with pytest.raises(ivr.Error, match="not one element"):
        float(a)
    with pytest.raises(ivr.Error, match="float32 or float64"):
        ivr.DeviceArray(ctx, (2,), "int16")
    with pytest.raises(ivr.Error, match=r"rank 0"):
        ivr.DeviceArray(ctx, ())
    a.close()
    a.close()  # twice is fine
    assert "closed" in repr(a)
    with pytest.raises(ivr.Error) as e:
        a.numpy()
    assert e.value.status == "IVR_ERROR_INVALID_HANDLE" and "closed" in e.value.message


@pytest.mark.parametrize("scene, vol", [(SCENE, volume()), (EA, blob())], ids=["tiny", "blob"])
def test_render_equals_context_render(ctx, scene, vol):
    with ivr.Session(ctx, scene, vol) as s:
        assert s.image_shape == ctx.render(scene, vol).shape and s.volume_shape == vol.shape
        image = s.render()
        assert image.dtype == np.float32 and image.shape == s.image_shape
        close(image.numpy(), ctx.render(scene, vol), rtol=0, atol_scale=1e-6)
        stats = s.last_stats()
        assert stats["samples"] > 0 and stats["kernel_seconds"] >= 0
        assert stats["step"] == scene["integrator"]["step"] and stats["device_bytes"] > 0
        np.testing.assert_array_equal(s.volume.numpy(), vol)
        if scene is EA:  # a quarter of the bricks are empty: skipped, to the same image
            assert stats["skipped_empty"] and stats["empty_fraction"] > 0.2
            off = ivr.Session(ctx, scene, vol, empty_space="off")
            close(off.render().numpy(), image.numpy(), rtol=0, atol_scale=1e-6)
            assert not off.last_stats()["skipped_empty"]


def test_render_follows_every_setter(ctx):
    scene, vol = dict(EA), blob()
    s = ivr.Session(ctx, scene, vol)
    rng = np.random.default_rng(1)

    def same():
        close(s.render().numpy(), ctx.render(scene, vol), rtol=0, atol_scale=1e-6)

    vol = rng.uniform(0, 1, (12, 10, 14)).astype(np.float32)  # another shape: the box follows
    s.set_volume(vol)
    assert s.volume_shape == (12, 10, 14)
    same()
    scene["tf"] = {"type": "gaussian", "gaussians": [
        {"mean": 0.5, "width": 0.2, "color": [0.9, 0.4, 0.1], "extinction": 5.0}]}
    s.set_tf(scene["tf"])
    same()
    scene["cameras"] = [{"orbit": {"views": 3, "radius": 2.5, "fov_y": 30, "width": 12,
                                   "height": 10}},
                        {"eye": [0.3, 0.4, 2], "target": [0, 0, 0], "up": [0, 1, 0],
                         "fov_y": 40, "width": 12, "height": 10}]
    s.set_cameras(scene["cameras"])
    assert s.image_shape == (4, 10, 12, 4)
    same()
    scene["integrator"] = {"scheme": "midpoint", "step": 0.3}
    s.set_integrator(scene["integrator"])
    same()
    scene["background"] = [0.5, 0.4, 0.3]
    s.set_background(scene["background"])
    same()
    scene["background"] = 0.25
    s.set_background(0.25)
    same()
    vol = (rng.uniform(0, 1, (8, 9, 7)) * 65535).astype(np.uint16)  # mapped to [0, 1]
    s.set_volume(vol)
    same()
    vol = rng.uniform(0, 1, (8, 9, 7))  # float64, from a device array
    s.set_volume(ivr.DeviceArray.from_numpy(ctx, vol))
    same()
    close(s.volume.numpy(), vol, rtol=1e-7, atol_scale=0)  # kept in the session's float32


def test_precision_f64(ctx):
    with ivr.Context(precision="f64") as c64:
        s = ivr.Session(c64, SCENE, volume())
        assert s.precision == "f64" and s.volume.dtype == np.float64
        image = s.render().numpy()
        # float64 kept: the one-shot render fills a float32 buffer, the session's array is not
        # rounded to float32 (most of its values are not float32 numbers).
        assert image.dtype == np.float64
        assert np.mean(image.astype(np.float32).astype(np.float64) != image) > 0.5
        np.testing.assert_array_equal(image.astype(np.float32), c64.render(SCENE, volume()))
        jacobian = s.jacobian(("background",)).numpy()
        assert jacobian.dtype == np.float64
        transmittance = 1 - image[..., 3]
        for c in range(3):  # d pixel_c / d background_c = T, the closed form
            np.testing.assert_allclose(jacobian[..., c, c], transmittance, rtol=0, atol=1e-14)
    s32 = ivr.Session(ctx, SCENE, volume(), precision="f64")  # per session, whatever the context
    assert s32.volume.dtype == np.float64


WRT = ("density", "tf", "background", "camera")


@pytest.mark.parametrize("mode", ["forward", "adjoint"])
def test_gradient_equals_context_grad(ctx, mode):
    target = np.random.default_rng(2).uniform(0, 0.6, (1, 5, 6, 4)).astype(np.float32)
    want_loss, want = ctx.gradient(SCENE, volume(), target, wrt=WRT, mode=mode)
    s = ivr.Session(ctx, SCENE, volume())
    s.set_target(target)
    info = {}
    loss, grads = s.gradient(wrt=WRT, mode=mode, info=info)
    assert info["mode"] == mode and list(grads) == list(WRT)
    assert loss.shape == (1,) and float(loss) == pytest.approx(want_loss, rel=1e-6, abs=1e-12)
    for group in WRT:
        assert grads[group].shape == want[group].shape, group
        close(grads[group].numpy(), want[group], rtol=1e-5, atol_scale=1e-5)
    # a target passed to the call (numpy, squeezed shape, or a device array) gives the same
    for t in (target[0], ivr.DeviceArray.from_numpy(s, target)):
        loss2, grads2 = s.gradient(t, wrt=("tf", "voxels:3,7-9"), mode=mode)
        assert float(loss2) == pytest.approx(float(loss), rel=1e-6)
        close(grads2["tf"].numpy(), want["tf"], rtol=1e-5, atol_scale=1e-5)
        close(grads2["voxels"].numpy(), want["density"].ravel()[[3, 7, 8, 9]], rtol=1e-5,
              atol_scale=1e-5)
    l1, g1 = s.gradient(wrt="density", mode=mode, loss="l1")
    want_l1, want_g1 = ctx.gradient(SCENE, volume(), target, wrt="density", mode=mode, loss="l1")
    assert float(l1) == pytest.approx(want_l1, rel=1e-6)
    close(g1["density"].numpy(), want_g1["density"], rtol=1e-5, atol_scale=1e-5)


def test_gradient_auto_deterministic_and_jacobian(ctx):
    target = np.full((1, 5, 6, 4), 0.3, np.float32)
    s = ivr.Session(ctx, SCENE, volume())
    s.set_target(target)
    a = s.gradient(mode="adjoint", deterministic=True)[1]["density"].numpy()
    b = s.gradient(mode="adjoint", deterministic=True)[1]["density"].numpy()
    np.testing.assert_array_equal(a, b)
    info = {}
    s.gradient(wrt=("tf",), info=info)
    assert info["mode"] in ("forward", "adjoint")
    J = s.jacobian(("camera", "background"))
    assert J.shape == (1, 5, 6, 4, 10) and J.dtype == np.float32
    want = ctx.jacobian(SCENE, volume(), wrt=("camera", "background"))
    close(J.numpy(), want, rtol=1e-5, atol_scale=1e-6)


def test_results_stay_valid_after_later_calls(ctx):
    rng = np.random.default_rng(3)
    s = ivr.Session(ctx, EA, blob())
    s.set_target(rng.uniform(0, 0.5, s.image_shape).astype(np.float32))
    image = s.render()
    loss, grads = s.gradient(wrt=("density", "tf"))
    view = s.volume
    kept = [image.numpy(), loss.numpy(), grads["density"].numpy(), grads["tf"].numpy(),
            view.numpy()]
    for _ in range(2):  # the session's output pools must not hand these buffers out again
        s.render()
        s.gradient(wrt=("density", "tf"))
        s.set_target(rng.uniform(0, 0.5, s.image_shape).astype(np.float32))
        s.gradient(wrt=("density", "tf"), mode="forward")
    other = blob(seed=9)
    s.set_volume(other)
    s.render()
    s.gradient()
    for array, values in zip([image, loss, grads["density"], grads["tf"], view], kept):
        np.testing.assert_array_equal(array.numpy(), values)
    np.testing.assert_array_equal(s.volume.numpy(), other)  # a new buffer after set_volume


def test_project_and_backproject(ctx):
    rng = np.random.default_rng(5)
    x = rng.uniform(0, 1, (12, 10, 8)).astype(np.float32)  # (Z, Y, X): every axis differs
    y = rng.uniform(-1, 1, (8, 16, 16, 1)).astype(np.float32)
    s = ivr.Session(ctx, TOMO, x)
    p = s.project()
    assert p.shape == (8, 16, 16, 1) and p.dtype == np.float32
    close(p.numpy(), ctx.project(TOMO, x), rtol=0, atol_scale=1e-6)
    other = rng.uniform(0, 1, x.shape).astype(np.float32)
    close(s.project(other).numpy(), ctx.project(TOMO, other), rtol=0, atol_scale=1e-6)
    b = s.backproject(y[..., 0])  # (views, H, W) is accepted from numpy
    assert b.shape == x.shape
    close(b.numpy(), ctx.backproject(TOMO, y, grid=x.shape), rtol=0, atol_scale=1e-5)
    # the dot-product test on device arrays: <N x, y> = <x, N^T y> to rounding
    for xs in (rng.uniform(-1, 1, x.shape), rng.uniform(0, 1, x.shape)):
        xd = ivr.DeviceArray.from_numpy(ctx, xs.astype(np.float32))
        yd = ivr.DeviceArray.from_numpy(ctx, rng.uniform(-1, 1, y.shape).astype(np.float32))
        nx, nty = s.project(xd), s.backproject(yd)
        lhs = np.dot(nx.numpy().ravel().astype(np.float64), yd.numpy().ravel())
        rhs = np.dot(xd.numpy().ravel().astype(np.float64), nty.numpy().ravel())
        assert abs(lhs - rhs) <= 1e-5 * max(abs(lhs), abs(rhs)) + 1e-9


def test_loss_equals_ivr_loss(ctx):
    rng = np.random.default_rng(4)
    s = ivr.Session(ctx, EA, blob())
    image = s.render()
    target = rng.uniform(0, 0.5, image.shape).astype(np.float32)
    t = ivr.DeviceArray.from_numpy(ctx, target)
    for kind in ("mse", "l1"):
        value = s.loss(image, t, kind)
        assert value.shape == (1,)
        want = ivr.loss(image.numpy(), t.numpy(), kind)
        assert float(value) == pytest.approx(want, rel=1e-6, abs=1e-12)
        assert float(s.loss(image.numpy(), target, kind)) == pytest.approx(want, rel=1e-6)
    with pytest.raises(ivr.Error, match="kind must be one of"):
        s.loss(image, t, "huber")


@pytest.mark.parametrize("kind, lr", [("adam", 0.03), ("sgd", 20.0)])
def test_density_optimizer_lowers_the_loss(ctx, kind, lr):
    truth = blob()
    start = np.clip(0.7 * truth + 0.1 * np.random.default_rng(6).random(truth.shape), 0, None)
    s = ivr.Session(ctx, EA, start.astype(np.float32))
    s.set_target(ctx.render(EA, truth))
    opt = ivr.DensityOptimizer(s, kind, lr=lr)
    view = s.volume
    losses = []
    for _ in range(12):
        loss, grads = s.gradient(wrt=("density",), mode="adjoint")
        s.step(opt, grads["density"])
        losses.append(float(loss))
    assert losses[-1] < 0.5 * losses[0], losses
    now = view.numpy()  # the view shows the steps
    assert now.min() >= 0 and np.abs(now - start).max() > 1e-3
    np.testing.assert_array_equal(now, s.volume.numpy())
    assert np.linalg.norm(now - truth) < np.linalg.norm(start - truth)
    # a numpy gradient is uploaded in the session's precision
    s.step(opt, np.zeros(truth.shape, np.float64))


def test_bad_inputs_leave_the_session_unchanged(ctx, other_ctx):
    vol = blob()
    s = ivr.Session(ctx, EA, vol)
    target = np.random.default_rng(7).uniform(0, 0.5, s.image_shape).astype(np.float32)
    s.set_target(target)
    opt = ivr.DensityOptimizer(s, "adam", lr=0.01)
    image, (loss, grads) = s.render().numpy(), s.gradient(wrt=("density", "tf"))
    loss, grads = float(loss), {k: v.numpy() for k, v in grads.items()}

    def bad(value, at):
        v = vol.copy()
        v[at] = value
        return v
    closed = ivr.DeviceArray.from_numpy(ctx, vol)
    closed.close()
    bad_target = target.copy()
    bad_target[1, 2, 3, 0] = np.nan
    cases = [
        (lambda: s.set_volume(vol[0]), r"shape \(Z, Y, X\), got \(16, 16\)", None),
        (lambda: s.set_volume(vol.astype(np.int32)), "dtype .* got int32", None),
        (lambda: s.set_volume(bad(np.nan, (1, 2, 3))), r"\(x, y, z\) = \(3, 2, 1\) is nan", None),
        (lambda: s.set_volume(bad(np.inf, (4, 5, 6))), r"\(6, 5, 4\) is inf", None),
        (lambda: s.set_volume(bad(-0.5, (15, 0, 2))), r"\(2, 0, 15\) is -0.5", None),
        (lambda: s.set_volume(ivr.DeviceArray.from_numpy(ctx, bad(np.nan, (0, 0, 1)))),
         r"\(1, 0, 0\) is nan", None),
        (lambda: s.set_volume(ivr.DeviceArray(ctx, (4, 4))), "densities are", None),
        (lambda: s.set_target(target[:, :8]), "target has shape", None),
        (lambda: s.set_target(bad_target), "target element 1164 is not finite", None),
        (lambda: s.set_target(ivr.DeviceArray.from_numpy(ctx, bad_target)), "not finite", None),
        (lambda: s.set_target(ivr.DeviceArray(ctx, (2, 16, 16, 3))), "target has shape", None),
        (lambda: s.set_volume(ivr.DeviceArray.from_numpy(other_ctx, vol)), "another context",
         "IVR_ERROR_WRONG_CONTEXT"),
        (lambda: s.gradient(ivr.DeviceArray.from_numpy(other_ctx, target)), "another context",
         "IVR_ERROR_WRONG_CONTEXT"),
        (lambda: s.set_volume(closed), "closed", "IVR_ERROR_INVALID_HANDLE"),
        (lambda: s.gradient(wrt=("density", "opacity")), "unknown parameter group 'opacity'",
         None),
        (lambda: s.gradient(mode="sideways"), "mode must be one of", None),
        (lambda: s.set_tf({"type": "piecewise_linear", "points": []}), "tf", None),
        (lambda: s.set_cameras([]), "at least one camera", None),
        (lambda: s.set_integrator({"scheme": "exact"}), "absorption model only", None),
        (lambda: s.set_background([0.1, float("nan"), 0.1]), "finite", None),
        (lambda: s.set_background([0.1, 0.2]), r"\[r, g, b\]", None),
        (lambda: s.step(opt, np.zeros((16, 16, 15), np.float32)),
         r"gradient has shape \(16, 16, 15\) but the densities are \(16, 16, 16\)", None),
        (lambda: s.step(opt, ivr.DeviceArray(ctx, (16, 16, 15))), "gradient has shape", None),
        (lambda: s.gradient(bad_target), "target element 1164 is not finite", None),
        (lambda: s.backproject(np.zeros((2, 16, 16, 2), np.float32)),
         r"lines has shape \(2, 16, 16, 2\) but the session's rays are \(2, 16, 16, 1\)", None),
        (lambda: s.step("adam", np.zeros(vol.shape, np.float32)), "DensityOptimizer", None),
        (lambda: ivr.DensityOptimizer(s, "lbfgs"), "kind must be one of", None),
        (lambda: ivr.DensityOptimizer(s, "adam", lr=0), "lr must be > 0", None),
    ]
    for call, match, status in cases:
        with pytest.raises(ivr.Error, match=match) as e:
            call()
        assert e.value.status == (status or "IVR_ERROR_INVALID_ARGUMENT"), e.value
        np.testing.assert_array_equal(s.render().numpy(), image, err_msg=match)
    np.testing.assert_array_equal(s.volume.numpy(), vol)
    assert s.volume_shape == vol.shape and s.image_shape == image.shape
    loss2, grads2 = s.gradient(wrt=("density", "tf"))  # the target is the one set first
    assert float(loss2) == pytest.approx(loss, rel=1e-6)
    for k in grads:
        close(grads2[k].numpy(), grads[k], rtol=1e-5, atol_scale=1e-6)


def test_missing_things_and_closed_handles(ctx):
    s = ivr.Session(ctx, SCENE)  # no volume anywhere
    with pytest.raises(ivr.Error, match="no densities"):
        s.render()
    s.set_volume(volume())
    with pytest.raises(ivr.Error, match="no target"):
        s.gradient()
    s.set_target(np.zeros((5, 6, 4), np.float32))  # (H, W, C) for one view
    s.set_cameras([dict(SCENE["cameras"][0], width=8)])  # another image size drops the target
    with pytest.raises(ivr.Error, match="no target"):
        s.gradient()
    # sessions and arrays keep their context alive; a closed session refuses every call
    c = ivr.Context()
    t = ivr.Session(c, SCENE, volume())
    a = ivr.DeviceArray(c, (1, 5, 6, 4))
    c.close()
    close(t.render().numpy(), ctx.render(SCENE, volume()), rtol=0, atol_scale=1e-6)
    assert float(t.loss(t.render(), a)) > 0
    t.close()
    assert repr(t) == "ivr.Session(closed)"
    for call in (t.render, lambda: t.set_volume(volume()), lambda: t.volume,
                 lambda: t.gradient(), lambda: ivr.DensityOptimizer(t)):
        with pytest.raises(ivr.Error, match="the session is closed") as e:
            call()
        assert e.value.status == "IVR_ERROR_INVALID_HANDLE"
    with ivr.Session(ctx, SCENE, volume()) as u:
        opt = ivr.DensityOptimizer(u)
        opt.close()
        with pytest.raises(ivr.Error, match="optimizer is closed"):
            u.step(opt, np.zeros((4, 5, 6), np.float32))


def run(session, target):
    loss, grads = session.gradient(target, wrt=("density", "tf"), mode="adjoint",
                                   deterministic=True)
    return [session.render().numpy(), loss.numpy(), grads["density"].numpy(),
            grads["tf"].numpy()]


def same_results(got, want):
    # render, loss and the fixed-point density gradient repeat bit for bit; the adjoint's TF sums
    # are atomic adds in any order
    for i, (g, w) in enumerate(zip(got, want)):
        if i < 3:
            np.testing.assert_array_equal(g, w)
        else:
            close(g, w, rtol=1e-5, atol_scale=1e-6)


def threaded(work, count):
    errors = []

    def guarded(i):
        try:
            work(i)
        except BaseException as e:  # noqa: BLE001 — reported below
            errors.append(e)
    threads = [threading.Thread(target=guarded, args=(i,)) for i in range(count)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if errors:
        raise errors[0]


def test_sessions_of_one_context_on_two_threads(ctx):
    vols = [blob(seed=10), blob(seed=11)]
    target = np.full((2, 16, 16, 4), 0.2, np.float32)
    want = [run(ivr.Session(ctx, EA, v), target) for v in vols]
    got = [[], []]

    def work(i):
        s = ivr.Session(ctx, EA, vols[i])
        for _ in range(3):
            got[i].append(run(s, target))
    threaded(work, 2)
    for i in range(2):
        for r in got[i]:
            same_results(r, want[i])


def test_one_session_from_two_threads(ctx):
    s = ivr.Session(ctx, EA, blob())
    target = ivr.DeviceArray.from_numpy(ctx, np.full((2, 16, 16, 4), 0.2, np.float32))
    want = run(s, target)
    got, turn, cond = [], [0], threading.Condition()

    def in_turn(i):  # thread 0, then 1, then 0, then 1
        for _ in range(2):
            with cond:
                cond.wait_for(lambda: turn[0] % 2 == i)
            got.append(run(s, target))
            with cond:
                turn[0] += 1
                cond.notify_all()
    threaded(in_turn, 2)
    threaded(lambda i: [got.append(run(s, target)) for _ in range(2)], 2)  # at once: serialised
    assert len(got) == 8
    for r in got:
        same_results(r, want)


def test_wrap_and_view_share_host_memory(ctx):
    """On PoCL (device memory = host memory) a wrapped array is the numpy array's own memory and a
    view is the device array's memory: no copies either way."""
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    d = ivr.DeviceArray.wrap(ctx, a)
    assert d.borrowed and d.shape == (3, 4) and d.dtype == np.float32
    v = d.view()
    assert np.shares_memory(v, a)
    a[0, 0] = 7.0
    assert v[0, 0] == 7.0
    np.testing.assert_array_equal(d.numpy(), a)
    with pytest.raises(ivr.Error, match="mapped"):
        d.upload(np.zeros(12, np.float32))
    del v  # the last user of the mapping: unmapped
    d.upload(np.ones(12, np.float32))
    np.testing.assert_array_equal(a, 1.0)
    # A result's view equals its download and keeps the array alive on its own.
    r = ivr.DeviceArray.from_numpy(ctx, np.linspace(0, 1, 5))
    view = r.view()
    del r
    np.testing.assert_array_equal(view, np.linspace(0, 1, 5))
    with pytest.raises(ivr.Error, match="C-contiguous"):
        ivr.DeviceArray.wrap(ctx, np.zeros((4, 4), np.float32)[:, ::2])
    with pytest.raises(ivr.Error, match="float32 or float64"):
        ivr.DeviceArray.wrap(ctx, np.zeros(3, np.int32))
