# test_rays.py — ray lists from Python: scene dicts with a "rays" array, (R, C) images and
# (R, 1) lines, Session.set_rays, tomography over sightlines, and errors naming the bad ray.
import numpy as np
import pytest

import ivr


def scene_of(rays, model="absorption", dims=(8, 8, 8)):
    return {"volume": {"synthetic": "sphere", "dims": list(dims)}, "model": model,
            "box": {"min": [-0.5] * 3, "max": [0.5] * 3},
            "tf": {"type": "identity", "extinction_scale": 2.0},
            "integrator": {"min_transmittance": 0}, "rays": rays}


def test_constant_density_closed_form_and_shapes():
    rays = np.array([[0, 0, 0, 1, 0, 0, 0, 0.3],          # inside
                     [-2, 0.1, 0, 1, 0, 0, 0, 1.8],       # from outside, ends inside
                     [0.1, 0.1, 0.1, 0, 1, 0, 0.2, 0.2],  # length 0
                     [0.2, -0.3, 0.1, 0, 0, 1, -np.inf, np.inf]])  # the whole chord
    lengths = np.array([0.3, 0.3, 0.0, 1.0])
    with ivr.Context(precision="f64") as ctx:
        volume = np.full((4, 4, 4), 0.75)
        scene = scene_of(rays, dims=(4, 4, 4))
        image = ctx.render(scene, volume=volume)
        assert image.shape == (4, 1)
        np.testing.assert_allclose(image[:, 0], np.exp(-2.0 * 0.75 * lengths), rtol=1e-6)
        lines = ctx.project(scene, volume=volume)
        assert lines.shape == (4, 1)
        # float32 out (computed in float64).
        np.testing.assert_allclose(lines[:, 0], 0.75 * lengths, rtol=1e-7, atol=1e-12)


def test_dot_product_and_cgls_over_sightlines():
    rng = np.random.default_rng(4)
    n = 4000
    stars = rng.uniform(-0.5, 0.5, (n, 3))
    rays = np.hstack([np.zeros((n, 3)), stars])            # (n, 6): observer → star
    scene = scene_of(rays)
    with ivr.Context(precision="f64") as ctx:
        truth = ctx.load_volume({"synthetic": "sphere", "dims": [8, 8, 8]}).astype(np.float64)
        x = rng.uniform(0, 1, truth.shape)
        y = rng.uniform(0, 1, (n, 1))
        nx = ctx.project(scene, volume=x)
        nty = ctx.backproject(scene, y)
        # float32 outputs of float64 sums (the float64 test of the pair is the C++ suite's).
        assert abs(np.vdot(nx, y) - np.vdot(x, nty)) <= 1e-6 * abs(np.vdot(nx, y))
        lines = ctx.project(scene, volume=truth)
        volume, history = ctx.tomo(scene, lines, solver="cgls", iterations=150)
        assert history[-1]["residual"] < 1e-4
        assert np.linalg.norm(volume - truth) / np.linalg.norm(truth) < 0.01


def test_session_switches_geometry_and_keeps_it_after_a_bad_list():
    cam = {"eye": [0.3, 1.2, 1.5], "target": [0, 0, 0], "up": [0, 0, 1], "width": 6,
           "height": 5, "projection": "orthographic", "ortho_height": 1.4}
    scene = scene_of(None, model="emission_absorption")
    del scene["rays"]
    scene["cameras"] = [cam]
    with ivr.Context() as ctx, ivr.Session(ctx, scene) as s:
        assert s.image_shape == (1, 5, 6, 4)
        rays = np.array([[0, 0, -1, 0, 0, 1, 0, np.inf]])
        s.set_rays(rays)
        assert s.image_shape == (1, 4)
        image = s.render().numpy()
        assert image.shape == (1, 4)
        s.set_target(image)
        loss, _ = s.gradient(wrt=["density"])
        assert float(loss) == 0.0
        with pytest.raises(ivr.Error, match=r"rays\[0\]\.direction: is zero"):
            s.set_rays(np.array([[0, 0, 0, 0, 0, 0, 0, 1.0]]))
        assert s.image_shape == (1, 4)
        with pytest.raises(ivr.Error, match="ray list"):
            s.gradient(wrt=["camera"])
        s.set_cameras([cam])
        assert s.image_shape == (1, 5, 6, 4)


def test_bad_arrays_are_refused():
    with ivr.Context() as ctx:
        with pytest.raises(ivr.Error, match=r"\(rays, 8\) or \(rays, 6\)"):
            ctx.render(scene_of(np.zeros((3, 7))))
        with pytest.raises(ivr.Error, match=r"rays\[1\]\.t_end: 0\.1 is before t_start 0\.5"):
            ctx.render(scene_of(np.array([[0, 0, 0, 1, 0, 0, 0, 1], [0, 0, 0, 1, 0, 0, 0.5, 0.1]])))
        with pytest.raises(ivr.Error, match=r"rays\[0\]\.origin\.x: is NaN"):
            ctx.project(scene_of(np.array([[np.nan, 0, 0, 1, 0, 0, 0, 1.0]])))


def test_ray_parameter_gradient_against_the_closed_form():
    # Constant density d, identity TF σ = a·d, absorption: I = exp(−a·d·L) with L the part of
    # [t_start, t_end] inside the box. With the dot loss (weights w): d/d t_end = −a·d·I·w where the
    # list's own end bounds the ray, 0 where the box face does; d/d t_start the opposite; origin
    # and direction 0 in a constant medium except through the box faces.
    rays = np.array([[0, 0, 0, 1, 0, 0, -0.1, 0.3],      # both ends inside
                     [0.1, 0.2, 0, 0, 1, 0, -0.2, 5.0],    # exits through the face y = 0.5
                     [0, 0, 0, 0, 0, 1, -np.inf, 0.25]])   # from the entry face z = −0.5
    d, a = 0.75, 2.0
    with ivr.Context(precision="f64") as ctx:
        volume = np.full((4, 4, 4), d)
        scene = scene_of(rays, dims=(4, 4, 4))
        image = np.exp(-a * d * np.array([0.4, 0.5, 0.75]))   # the closed form
        np.testing.assert_allclose(ctx.render(scene, volume=volume)[:, 0], image, rtol=1e-7)
        weights = np.array([[1.0], [2.0], [-0.5]])
        info = {}
        _, g = ctx.gradient(scene, volume, weights, wrt=["rays"], loss="dot", info=info)
        assert info["mode"] == "forward"
        g = g["rays"]
        assert g.shape == (3, 8)
        w = weights[:, 0]
        np.testing.assert_allclose(g[:, 7], [-a * d * image[0] * w[0], 0, -a * d * image[2] * w[2]],
                                   rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(g[:, 6], [a * d * image[0] * w[0], a * d * image[1] * w[1], 0],
                                   rtol=1e-9, atol=1e-12)
        # Ray 1 leaves through y = 0.5: moving its origin along y shortens it one for one.
        np.testing.assert_allclose(g[1, 1], a * d * image[1] * w[1], rtol=1e-9)
        # Ray 2 enters through z = −0.5: moving its origin along z moves its end with it (t_end is
        # fixed in t) but not the entry face: L = t_end + 0.5 + o_z.
        np.testing.assert_allclose(g[2, 2], -a * d * image[2] * w[2], rtol=1e-9)
        with pytest.raises(ivr.Error, match="'rays'"):
            ctx.gradient(scene, volume, weights, wrt=["rays"], mode="adjoint")
