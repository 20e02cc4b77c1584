"""test_demo_figures.py — scripts/demo_figures.py: both pictures, their checks, a small run."""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import matplotlib.image

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "..", "scripts", "demo_figures.py")
sys.path.insert(0, os.path.dirname(SCRIPT))
import demo_figures as figures  # noqa: E402

IVR = os.environ.get("IVR_CLI")


def images(h=48, w=64, seed=7):
    rng = np.random.default_rng(seed)
    target = rng.uniform(0, 1, (h, w, 4)).astype(np.float32)
    before = np.full_like(target, 0.5)
    after = (target + rng.normal(0, 0.01, target.shape)).astype(np.float32)
    return target, before, after


def test_compare_has_four_panels_of_at_least_256_pixels_and_a_readable_png(tmp_path):
    target, before, after = images()
    out = str(tmp_path / "compare.png")
    sizes = figures.compare_figure(target, before, after, out)
    assert len(sizes) == 4
    for w, h in sizes:
        # The 48 x 64 images are scaled by 256 / 48: panels of at least 256 pixels each way.
        assert w >= 256 and h >= 256, sizes
        assert w / h == pytest.approx(64 / 48, rel=0.02)
    png = matplotlib.image.imread(out)
    assert png.shape[1] >= 4 * 256 and png.shape[0] >= 256
    assert np.all(np.isfinite(png))


def test_compare_of_a_perfect_match_and_of_black_images_draws(tmp_path):
    target = np.zeros((32, 32, 1), np.float32)  # one channel (absorption): grey
    sizes = figures.compare_figure(target, target + 0.2, target, str(tmp_path / "c.png"))
    assert all(w >= 256 for w, _ in sizes)
    assert figures.psnr(target, target) == math.inf
    assert figures.db_text(math.inf) == "∞"


def test_compare_rejects_mismatched_or_non_finite_images(tmp_path):
    target, before, after = images()
    with pytest.raises(figures.FigureError, match="after image has shape"):
        figures.compare_figure(target, before, after[:, :-1], str(tmp_path / "c.png"))
    after[3, 4, 0] = np.nan
    with pytest.raises(figures.FigureError, match="after image has a non-finite value"):
        figures.compare_figure(target, before, after, str(tmp_path / "c.png"))
    assert not (tmp_path / "c.png").exists()


def test_psnr_and_relative_error_follow_ivr_definitions():
    a = np.zeros((2, 2, 4))
    b = np.full((2, 2, 4), 0.1)  # MSE 0.01 over every channel: 20 dB
    assert figures.psnr(a, b) == pytest.approx(20.0)
    truth = np.ones((2, 2, 2))
    assert figures.relative_error(truth * 1.1, truth) == pytest.approx(0.1)
    assert figures.relative_error(truth * 0, truth * 0) == 0.0


def test_display_is_srgb_encoded_and_clipped():
    linear = np.array([[[0.0, 0.5, 2.0, 1.0]]])
    shown = figures.displayable(linear)
    assert shown.shape == (1, 1, 3)
    assert shown[0, 0] == pytest.approx([0.0, 0.7353569, 1.0], abs=1e-6)


def test_slices_figure_writes_and_rejects_other_shapes(tmp_path):
    truth = np.zeros((8, 10, 12), np.float32)
    truth[2:6, 3:7, 4:8] = 1
    out = str(tmp_path / "slices.png")
    figures.slices_figure(truth, truth * 0.9, out, "title")
    assert matplotlib.image.imread(out).shape[0] > 500
    with pytest.raises(figures.FigureError, match="shape"):
        figures.slices_figure(truth, truth[:, :, :-1], out)
    bad = truth.copy()
    bad[0, 0, 0] = np.inf
    with pytest.raises(figures.FigureError, match="reconstruction volume has a non-finite"):
        figures.slices_figure(truth, bad, out)


def test_view_scene_keeps_view_0_of_an_orbit_at_the_new_size():
    scene = {"cameras": [{"orbit": {"views": 8, "start": 30, "width": 64, "height": 32}},
                         {"eye": [0, 0, 2]}], "volume": {"synthetic": "shepp_logan"}}
    s = figures.view_scene(scene, "v.npy", 256)
    assert s["cameras"] == [{"orbit": {"views": 1, "start": 30, "width": 256, "height": 128}}]
    assert s["volume"] == {"file": os.path.abspath("v.npy")}
    assert scene["cameras"][0]["orbit"]["views"] == 8  # the caller's scene is left as it was


@pytest.mark.skipif(not IVR, reason="IVR_CLI (the ivr program) is not set")
def test_end_to_end_on_a_small_reconstruction(tmp_path):
    def ivr(*args):
        r = subprocess.run([IVR, *args], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    d = str(tmp_path)
    ivr("phantom", "shepp-logan", "--size", "16", "-o", d + "/truth.npy")
    tf = {"type": "piecewise_linear", "points": [
        {"density": 0, "color": [0, 0, 0], "extinction": 0},
        {"density": 1, "color": [1, 0.7, 0.4], "extinction": 8},
        {"density": 2, "color": [0.5, 0.8, 1], "extinction": 16}]}
    scene = {"volume": {"file": "truth.npy"}, "model": "emission_absorption", "tf": tf,
             "background": [0, 0, 0], "integrator": {"scheme": "midpoint", "step": 0.5},
             "cameras": [{"orbit": {"views": 4, "axis": [0, 0, 1], "start": 30, "radius": 2.2,
                                    "fov_y": 40, "width": 24, "height": 24}}]}
    with open(d + "/scene.json", "w") as f:
        json.dump(scene, f)
    ivr("render", d + "/scene.json", "-o", d + "/targets.npy")
    ivr("reconstruct", d + "/scene.json", "--targets", d + "/targets.npy", "--init",
        "constant:0.5", "--iterations", "6", "-o", d + "/r")

    # View 0 at the scene's own size is exactly the target the reconstruction saw.
    view = figures.render(IVR, scene, d + "/truth.npy", 24, d, "check")
    assert np.array_equal(view, np.load(d + "/targets.npy")[0])

    args = [sys.executable, SCRIPT, "--ivr", IVR, "--scene", d + "/scene.json", "--truth",
            d + "/truth.npy", "--result", d + "/r_density.npy", "--start", "0.5",
            "--loss-csv", d + "/r_loss.csv", "-o", d + "/fig"]
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    compare = matplotlib.image.imread(d + "/fig_compare.png")
    assert compare.shape[1] >= 4 * 256 and compare.shape[0] >= 256
    assert matplotlib.image.imread(d + "/fig_slices.png").shape[0] > 500

    # A bad input: status 1 and one line naming the problem.
    bad = subprocess.run(args[:-2] + ["--size", "4", "-o", d + "/bad"], capture_output=True,
                         text=True)
    assert bad.returncode == 1
    assert bad.stderr == "demo_figures: error: --size must be >= 16, got 4\n"
    assert not os.path.exists(d + "/bad_compare.png")
