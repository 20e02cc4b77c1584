"""test_reconstruct.py — the Python binding's inverse rendering: densities of a small phantom from
its renders, a TF from images, progress, checkpoints and resumption, viewpoint selection,
entropy and PSNR, and ivr.Error with a useful message for bad arguments."""
import numpy as np
import pytest

import ivr

# A 16^3 phantom's scene (the volume is passed in), 8 views of 32^2 on a tilted orbit.
TF = {"type": "piecewise_linear", "points": [
    {"density": 0, "color": [0, 0, 0], "extinction": 0},
    {"density": 1, "color": [1, 0.7, 0.4], "extinction": 8},
    {"density": 2, "color": [0.5, 0.8, 1], "extinction": 16}]}
SCENE = {"model": "emission_absorption", "tf": TF, "background": [0, 0, 0],
         "cameras": [{"orbit": {"views": 8, "axis": [0.3, 0.2, 1], "start": 5, "radius": 2.2,
                                "fov_y": 40, "width": 32, "height": 32}}],
         "integrator": {"scheme": "midpoint", "step": 0.5}}
TRUTH = ivr.phantom("shepp-logan", 16)
START = np.full_like(TRUTH, 0.5)


def error(v):
    return np.linalg.norm(v - TRUTH) / np.linalg.norm(TRUTH)


@pytest.fixture(scope="module")
def ctx():
    with ivr.Context() as c:
        yield c


@pytest.fixture(scope="module")
def targets(ctx):
    return ctx.render(SCENE, TRUTH)


def test_density_from_renders_improves_the_volume_error(ctx, targets):
    out = ctx.reconstruct(SCENE, targets, volume=START, iterations=30, init="constant")
    v = out["volume"]
    assert v.shape == (16, 16, 16) and v.dtype == np.float32 and "tf" not in out
    assert np.isfinite(v).all() and v.min() >= 0
    assert error(v) < 0.9 * error(START)
    h = out["history"]
    assert [e["iteration"] for e in h] == list(range(1, 31))
    assert h[-1]["loss"] < 0.5 * h[0]["loss"] and h[-1]["level"] == out["levels"] - 1
    assert out["iterations"] == 30 and not out["stopped"] and out["optimizer"] == "adam"
    # The estimate renders closer to the targets than the start does.
    assert ivr.psnr(ctx.render(SCENE, v), targets) > ivr.psnr(ctx.render(SCENE, START), targets)


def test_tf_mode_returns_the_tf_rows(ctx, targets):
    wrong = {"type": "piecewise_linear", "points": [
        {"density": 0, "color": [0, 0, 0], "extinction": 0},
        {"density": 1, "color": [0.7, 0.9, 0.28], "extinction": 10.4},
        {"density": 2, "color": [0.35, 0.56, 0.7], "extinction": 11.2}]}
    out = ctx.reconstruct(dict(SCENE, tf=wrong), targets, volume=TRUTH, wrt=("tf",),
                          iterations=6)
    assert out["tf"].shape == (3, 4) and out["tf"].dtype == np.float64
    assert "volume" not in out and out["optimizer"] == "lbfgs" and out["levels"] == 1
    assert out["history"][-1]["loss"] < 0.2 * out["history"][0]["loss"]
    assert out["tf"][1, 3] != 10.4
    # Both at once: adam for everything, both arrays back.
    both = ctx.reconstruct(dict(SCENE, tf=wrong), targets, volume=TRUTH, wrt="density,tf",
                           iterations=3, levels=1)
    assert both["tf"].shape == (3, 4) and both["volume"].shape == (16, 16, 16)
    assert both["optimizer"] == "adam"


def test_progress_stops_and_a_checkpoint_resumes(ctx, targets, tmp_path):
    options = dict(volume=START, iterations=10, init="constant")
    seen = []

    def stop_at_four(entry):
        seen.append(entry)
        return entry["iteration"] < 4

    prefix = tmp_path / "run"
    first = ctx.reconstruct(SCENE, targets, progress=stop_at_four, checkpoint=prefix, **options)
    assert first["stopped"] and first["iterations"] == 4 and len(seen) == 4
    assert (tmp_path / "run_checkpoint.json").exists()
    resumed = ctx.reconstruct(SCENE, targets, checkpoint=prefix, resume=True, **options)
    assert resumed["iterations"] == 10 and not resumed["stopped"]
    assert [e["loss"] for e in resumed["history"][:4]] == [e["loss"] for e in seen]
    whole = ctx.reconstruct(SCENE, targets, **options)
    # The adjoint's float atomics sum in thread order: close, not necessarily bit-equal.
    np.testing.assert_allclose(resumed["volume"], whole["volume"], atol=1e-3)

    def fails(entry):
        raise KeyError("from progress")

    with pytest.raises(KeyError, match="from progress"):
        ctx.reconstruct(SCENE, targets, progress=fails, **options)


def test_viewpoint_returns_a_camera_of_higher_entropy(ctx):
    best = ctx.viewpoint(SCENE, TRUTH, view=1, iterations=5)
    cam = best["camera"]
    assert set(cam) == {"eye", "target", "up", "fov_y", "width", "height"}
    assert (cam["width"], cam["height"], cam["fov_y"]) == (32, 32, 40)
    assert np.linalg.norm(np.subtract(cam["eye"], cam["target"])) == pytest.approx(2.2)
    assert 0 < best["entropy_start"] <= best["entropy_best"] <= 1
    assert len(best["history"]) == 6 and best["history"][0]["iteration"] == 0
    assert best["history"][0]["entropy"] == best["entropy_start"]
    # The camera is a scene camera: its render has the entropy reported.
    image = ctx.render(dict(SCENE, cameras=[cam]), TRUTH)
    assert ivr.image_entropy(image) == pytest.approx(best["entropy_best"], abs=1e-6)
    steps = []
    ivr.viewpoint(SCENE, volume=TRUTH, iterations=4, progress=lambda e: steps.append(e) or
                  e["iteration"] < 2)
    assert [s["iteration"] for s in steps] == [0, 1, 2]


def test_psnr_and_entropy():
    a = np.zeros((2, 3, 4), np.float32)
    assert ivr.psnr(a, a) == np.inf
    assert ivr.psnr(a, a + 0.1) == pytest.approx(20.0, abs=1e-5)
    flat = np.full((1, 4, 4, 4), 0.5, np.float32)
    assert ivr.image_entropy(flat) == pytest.approx(1.0)
    with pytest.raises(ivr.Error, match="differ in shape"):
        ivr.psnr(a, a[0])


def test_bad_arguments_raise_with_a_message(ctx, targets):
    def fails(match, status="IVR_ERROR_INVALID_ARGUMENT", **kw):
        with pytest.raises(ivr.Error, match=match) as e:
            ctx.reconstruct(SCENE, kw.pop("targets", targets), volume=START, iterations=3, **kw)
        assert e.value.status == status

    fails("wrt names what is optimised.*'camera'", wrt=("camera",))
    fails("wrt is empty", wrt=())
    fails(r"targets have shape \(8, 32, 32\) but the scene renders \(8, 32, 32, 4\)",
          targets=targets[..., 0])
    fails("lr must be > 0", lr=-1)
    fails("lbfgs is for small parameter sets", optimizer="lbfgs")
    fails("sgd needs an explicit lr", optimizer="sgd")
    fails("optimizer must be one of auto, adam, sgd, lbfgs, got 'newton'", optimizer="newton")
    fails("init must be one of", init="random")
    fails("resume=True needs checkpoint=", resume=True)
    fails("checkpoint", status="IVR_ERROR_IO", checkpoint="/nonexistent-ivr/run", resume=True)
    with pytest.raises(ivr.Error, match="view 9 does not exist"):
        ctx.viewpoint(SCENE, TRUTH, view=9)
    with pytest.raises(ivr.Error, match="iterations must be >= 0"):
        ctx.viewpoint(SCENE, TRUTH, iterations=-1)
