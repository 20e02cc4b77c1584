"""ivr.mpi under `mpirun -np N python3 -m pytest test_mpi.py` (CTest label mpi): every rank's render,
gradient, projection and back-projection, each rank doing its share of the views, equal one
process's (float64: the images and gradients within 1e-12 of the largest entry; the lines bit for
bit, the float32 back-projection within 1e-6; with deterministic=True the density gradient one
process's bit for bit, over views and over slabs); the render and the density, TF and background
gradients over slabs (within 1e-12; the camera's, by forward lanes, 1e-10) and over independent
segments (within 1e-12; the camera's 1e-10); CGLS over views and over slabs (the float32 volume within 1e-6, the
residuals within 1e-10; CGLS, SIRT and LSQR); a reconstruction sharing each batch's views, and
one over slabs and over segments (losses within 1e-10, a stop
on one rank stopping all); shares of the views by weight (render, projection, CGLS, the
deterministic density gradient, a reconstruction whose batch keeps a view on every rank) and of
the slabs (render, gradients, CGLS and a reconstruction over slabs sized by weight); more
ranks than views; a ray list; bad input.
Each rank also computes the one-process result itself, as the reference."""
import copy
import json
import os

import numpy as np
import pytest

# (Not skipped where absent: scripts/install-deps.sh installs python3-mpi4py with Open MPI.)
from mpi4py import MPI  # noqa: E402

import ivr  # noqa: E402
import ivr.mpi  # noqa: E402

with open(os.path.join(os.path.dirname(__file__), "../../../tests/data/binding_scene.json")) as f:
    BASE = json.load(f)

COMM = MPI.COMM_WORLD


def volume():
    i = np.arange(4 * 5 * 6, dtype=np.float64)
    return (0.4 + 0.3 * np.sin(0.7 * i)).astype(np.float32).reshape(4, 5, 6)


def scene_of(views):
    """The binding scene seen from `views` cameras around it."""
    s = copy.deepcopy(BASE)
    cam = BASE["cameras"][0]
    s["cameras"] = []
    for k in range(views):
        a = 2 * np.pi * k / views
        s["cameras"].append(dict(cam, eye=[2 * np.sin(a) + 0.3, 0.4, 2 * np.cos(a)]))
    return s


@pytest.fixture(scope="module")
def ctx():
    with ivr.Context(precision="f64") as c:
        yield c


def close(a, b, what):
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, (what, a.shape, b.shape)
    scale = max(np.max(np.abs(a)), 1e-300)
    err = np.max(np.abs(a - b)) / scale
    assert np.all(np.isfinite(b)) and err <= 1e-12, f"{what}: {err} on {COMM.Get_size()} ranks"


def test_view_shares():
    assert ivr.mpi.view_shares(7, 3) == [(0, 3), (3, 2), (5, 2)]
    assert ivr.mpi.view_shares(2, 4) == [(0, 1), (1, 1)]
    with pytest.raises(ivr.Error):
        ivr.mpi.view_shares(3, 0)


@pytest.mark.parametrize("views", [1, 3, 5])
def test_render_and_gradient_equal_one_process(ctx, views):
    s, v = scene_of(views), volume()
    one = ctx.render(s, v)
    close(one, ivr.mpi.render(ctx, s, v), f"render of {views} views")
    target = 0.8 * one + 0.05
    for loss in ("mse", "dot"):
        wrt = ("density", "tf", "background", "camera")
        l1, g1 = ctx.gradient(s, v, target, wrt=wrt, mode="adjoint", loss=loss)
        ln, gn = ivr.mpi.gradient(ctx, s, v, target, wrt=wrt, mode="adjoint", loss=loss)
        assert abs(ln - l1) <= 1e-12 * abs(l1) + 1e-300, (views, loss, ln, l1)
        assert sorted(gn) == sorted(g1)
        for name in g1:
            close(g1[name], gn[name], f"{loss} gradient {name} of {views} views")
    # Every rank got the same result.
    assert all(np.array_equal(x, gn["density"]) for x in COMM.allgather(gn["density"]))


@pytest.mark.parametrize("precision", ["f32", "f64"])
@pytest.mark.parametrize("split", ["views", "slabs"])
def test_deterministic_gradient_is_one_process_bit_for_bit(precision, split):
    # (over slabs the rays' states pass between the ranks: the in-core fixed point's bits)
    s, v = scene_of(5), volume()
    with ivr.Context(precision=precision) as c:
        target = 0.8 * c.render(s, v) + 0.05
        wrt = ("density", "tf")
        l1, g1 = c.gradient(s, v, target, wrt=wrt, mode="adjoint", deterministic=True)
        ln, gn = ivr.mpi.gradient(c, s, v, target, wrt=wrt, mode="adjoint", deterministic=True,
                                  split=split)
    assert np.array_equal(g1["density"], gn["density"]), \
        f"{precision} {split}: {np.count_nonzero(g1['density'] != gn['density'])} voxels differ"
    tol = 1e-12 if precision == "f64" else 2e-5
    err = np.max(np.abs(g1["tf"] - gn["tf"])) / np.max(np.abs(g1["tf"]))
    assert err <= tol and abs(ln - l1) <= tol * abs(l1), (precision, split, err, ln, l1)


@pytest.mark.parametrize("views", [1, 4])
def test_project_and_backproject_equal_one_process(ctx, views):
    s, v = dict(scene_of(views), model="absorption"), volume()
    one = ctx.project(s, v)
    many = ivr.mpi.project(ctx, s, v)
    assert many.shape == one.shape and np.array_equal(many, one), "the lines differ"
    bp_one = ctx.backproject(s, one, grid=v.shape)
    bp_many = ivr.mpi.backproject(ctx, s, one, grid=v.shape)
    assert bp_many.shape == bp_one.shape
    # float32 outputs: the parts' sum rounds differently from the one process's.
    err = np.max(np.abs(bp_many - bp_one)) / np.max(np.abs(bp_one))
    assert err <= 1e-6, f"backproject of {views} views on {COMM.Get_size()} ranks: {err}"


@pytest.mark.parametrize("model", ["emission_absorption", "absorption"])
def test_render_and_gradient_over_slabs_equal_one_process(ctx, model):
    s, v = dict(scene_of(3), model=model), volume()
    one = ctx.render(s, v)
    close(one, ivr.mpi.render(ctx, s, v, split="slabs"), f"{model} render over slabs")
    target = 0.8 * one + 0.05
    wrt = ("density", "tf", "background", "camera")
    l1, g1 = ctx.gradient(s, v, target, wrt=wrt, mode="adjoint")
    ln, gn = ivr.mpi.gradient(ctx, s, v, target, wrt=wrt, split="slabs")
    assert abs(ln - l1) <= 1e-12 * abs(l1), (ln, l1)
    assert sorted(gn) == sorted(g1)
    for name in wrt[:3]:
        close(g1[name], gn[name], f"{model} {name} gradient over slabs")
    # The camera's: forward lanes over slabs, the adjoint in one process.
    err = np.max(np.abs(gn["camera"] - g1["camera"])) / np.max(np.abs(g1["camera"]))
    assert err <= 1e-10, f"{model} camera gradient over slabs: {err}"
    assert all(np.array_equal(x, gn["density"]) for x in COMM.allgather(gn["density"]))


@pytest.mark.parametrize("scheme", ["trapezoid", "preintegrated"])
def test_endpoint_gradients_over_slabs_equal_one_process(ctx, scheme):
    # (each slab's bricks hold its neighbours' halo planes; their gradients are sent back)
    s, v = dict(scene_of(3), integrator={"scheme": scheme, "step": 0.5}), volume()
    target = 0.8 * ctx.render(s, v) + 0.05
    wrt = ("density", "tf")
    l1, g1 = ctx.gradient(s, v, target, wrt=wrt, mode="adjoint")
    ln, gn = ivr.mpi.gradient(ctx, s, v, target, wrt=wrt, split="slabs")
    assert abs(ln - l1) <= 1e-12 * abs(l1), (ln, l1)
    for name in wrt:
        close(g1[name], gn[name], f"{scheme} {name} gradient over slabs")


@pytest.mark.parametrize("scheme", ["midpoint", "trapezoid"])
def test_render_and_gradient_over_segments_equal_one_process(ctx, scheme):
    # Each rank's segment of every ray marched at once from transmittance 1, composited in order
    # (no early termination: a segment cannot know the transmittance in front of it).
    s = dict(scene_of(3), integrator={"scheme": scheme, "step": 0.5, "min_transmittance": 0})
    v = volume()
    one = ctx.render(s, v)
    close(one, ivr.mpi.render(ctx, s, v, split="segments"), f"{scheme} render over segments")
    target = 0.8 * one + 0.05
    wrt = ("density", "tf", "background")
    l1, g1 = ctx.gradient(s, v, target, wrt=wrt, mode="adjoint")
    _, g1c = ctx.gradient(s, v, target, wrt=("camera",), mode="adjoint")
    ln, gn = ivr.mpi.gradient(ctx, s, v, target, wrt=wrt, split="segments")
    assert abs(ln - l1) <= 1e-12 * abs(l1), (ln, l1)
    assert sorted(gn) == sorted(g1)
    for name in wrt:
        close(g1[name], gn[name], f"{scheme} {name} gradient over segments")
    # The camera's: each rank's segments' tangents composited with the others'.
    _, gc = ivr.mpi.gradient(ctx, s, v, target, wrt=("camera",), split="segments")
    err = np.max(np.abs(gc["camera"] - g1c["camera"])) / np.max(np.abs(g1c["camera"]))
    assert err <= 1e-10, f"{scheme} camera gradient over segments: {err}"


@pytest.mark.parametrize("split", ["slabs", "segments"])
def test_each_rank_holding_only_its_slab_equals_the_whole_volume(ctx, split):
    # (ivr_scene_set_volume_slab: a rank's planes alone; the results those of the whole volume)
    s = dict(scene_of(3), integrator={"scheme": "midpoint", "step": 0.5, "min_transmittance": 0})
    v = volume()
    first, last = ivr.mpi.slab(v.shape[0], ctx=ctx)
    mine = v[first:last + 1].copy()
    whole = ivr.mpi.render(ctx, s, v, split=split)
    assert np.array_equal(ivr.mpi.render(ctx, s, mine, split=split, nz=v.shape[0]), whole)
    target = 0.8 * whole + 0.05
    wrt = ("density", "tf")
    l1, g1 = ivr.mpi.gradient(ctx, s, v, target, wrt=wrt, split=split)
    ln, gn = ivr.mpi.gradient(ctx, s, mine, target, wrt=wrt, split=split, nz=v.shape[0],
                              gather=False)
    assert abs(ln - l1) <= 1e-12 * abs(l1)
    close(g1["tf"], gn["tf"], f"tf over {split}, each rank its slab")
    # gather=False: this rank's planes, the shared ones complete (the joined gradient's own)
    assert gn["density"].shape == mine.shape
    close(g1["density"][first:last + 1], gn["density"], f"density over {split}, its slab")
    options = dict(volume=np.full_like(mine, 0.3), wrt=("density",), iterations=2, batch=3,
                   levels=1, optimizer="sgd", lr=1.0, seed=5)
    out = ivr.mpi.reconstruct(ctx, s, whole, split=split, nz=v.shape[0], gather=False, **options)
    ref = ivr.mpi.reconstruct(ctx, s, whole, split=split,
                              **dict(options, volume=np.full_like(v, 0.3)))
    assert out["volume"].shape == mine.shape
    err = np.max(np.abs(out["volume"] - ref["volume"][first:last + 1]))
    assert err <= 1e-6, f"reconstruct over {split}, each rank its slab: {err}"
    with pytest.raises(ivr.Error, match="planes"):  # another rank's slab's size
        ivr.mpi.render(ctx, s, v[:1], split=split, nz=v.shape[0])
    with pytest.raises(ivr.Error, match="over slabs or segments"):
        ivr.mpi.render(ctx, s, mine, nz=v.shape[0])


@pytest.mark.parametrize("split", ["views", "slabs"])
@pytest.mark.parametrize("nonneg", [False, True])
@pytest.mark.parametrize("solver", ["cgls", "sirt", "lsqr"])
def test_tomo_equals_one_process(ctx, split, nonneg, solver):
    s, v = dict(scene_of(5), model="absorption"), volume()
    lines = ctx.project(s, v)
    lines = lines * (1.0 + 0.05 * np.sin(np.arange(lines.size))).reshape(lines.shape)
    options = dict(iterations=5, nonneg=nonneg, tikhonov=0.0 if nonneg else 1e-3, grid=v.shape,
                   solver=solver)
    one, h1 = ctx.tomo(s, lines, **options)
    many, h = ivr.mpi.tomo(ctx, s, lines, split=split, **options)
    assert many.shape == one.shape == v.shape and many.dtype == np.float32
    # float32 outputs of float64 iterates: within their rounding.
    err = np.max(np.abs(many.astype(np.float64) - one)) / np.max(np.abs(one))
    assert err <= 1e-6, f"tomo over {split} on {COMM.Get_size()} ranks: {err}"
    assert len(h) == len(h1)
    for a, b in zip(h, h1):
        assert abs(a["residual"] - b["residual"]) <= 1e-10 * b["residual"] + 1e-15, (a, b)
    assert all(np.array_equal(x, many) for x in COMM.allgather(many)), "ranks differ"


@pytest.mark.parametrize("solver", ["cgls", "sirt", "lsqr"])
def test_tv_tomo_over_views_and_slabs_equals_one_process(ctx, solver):
    s, v = dict(scene_of(5), model="absorption"), volume()
    lines = ctx.project(s, v)
    options = dict(iterations=5, tv=1e-3, tv_reweight=2, grid=v.shape, solver=solver)
    one, h1 = ctx.tomo(s, lines, **options)
    for split in ("views", "slabs"):  # (over slabs each rank the TV rows of its own planes)
        many, h = ivr.mpi.tomo(ctx, s, lines, split=split, **options)
        err = np.max(np.abs(many.astype(np.float64) - one)) / np.max(np.abs(one))
        # (the one process's TV by the device's kernels, the ranks' on host vectors: 1e-6)
        assert err <= 1e-6, f"TV {solver} over {split} on {COMM.Get_size()} ranks: {err}"
        for a, b in zip(h, h1):
            assert abs(a["residual"] - b["residual"]) <= 1e-10 * b["residual"] + 1e-15, (split, a, b)


def test_reconstruct_follows_one_process(ctx):
    s, v = scene_of(6), volume()
    targets = ctx.render(s, v)
    options = dict(volume=np.zeros_like(v), wrt=("density", "tf"), iterations=8, batch=3,
                   levels=1, init="constant", init_value=0.3, seed=5)
    one = ctx.reconstruct(s, targets, **options)
    seen = []
    many = ivr.mpi.reconstruct(ctx, s, targets, progress=seen.append, **options)
    assert len(seen) == len(one["history"]) == len(many["history"]) == 8
    for a, b in zip(many["history"], one["history"]):
        assert a["views"] == b["views"] and abs(a["loss"] - b["loss"]) <= 1e-10 * b["loss"], (a, b)
    err = np.max(np.abs(many["volume"].astype(np.float64) - one["volume"])) / \
        np.max(np.abs(one["volume"]))
    assert err <= 1e-6, f"reconstruct on {COMM.Get_size()} ranks: {err}"
    assert all(np.array_equal(x, many["volume"]) for x in COMM.allgather(many["volume"]))
    # A stop asked for on one rank stops every rank after the same iteration.
    stop_at = 3 if COMM.Get_rank() == COMM.Get_size() - 1 else 100
    stopped = ivr.mpi.reconstruct(ctx, s, targets,
                                  progress=lambda e: e["iteration"] < stop_at, **options)
    assert stopped["stopped"] and len(stopped["history"]) == 3


@pytest.mark.parametrize("split", ["slabs", "segments"])
def test_reconstruct_over_slabs_follows_one_process(ctx, split):
    # Each rank one slab of the 4 planes (3 cells: 2 or 3 ranks), both priors across the slabs;
    # SGD, whose steps are linear in the gradient (Adam's per-voxel scaling would magnify the
    # rounding of a voxel whose gradient is rounding noise). (No early termination: over segments
    # a segment cannot know the transmittance in front of it.)
    s, v = scene_of(6), volume()
    s["integrator"] = {"scheme": "midpoint", "step": 0.5, "min_transmittance": 0}
    targets = ctx.render(s, v)
    options = dict(volume=np.full_like(v, 0.3), wrt=("density", "tf"), iterations=5, batch=4,
                   levels=1, optimizer="sgd", lr=1.0, tv=0.05, smoothness=0.02, seed=5)
    one = ctx.reconstruct(s, targets, **options)
    many = ivr.mpi.reconstruct(ctx, s, targets, split=split, **options)
    assert len(many["history"]) == len(one["history"]) == 5
    for a, b in zip(many["history"], one["history"]):
        assert a["views"] == b["views"] and abs(a["loss"] - b["loss"]) <= 1e-12 * b["loss"], (a, b)
        assert abs(a["prior"] - b["prior"]) <= 1e-12 * abs(b["prior"]) + 1e-300, (a, b)
    assert many["volume"].shape == v.shape
    # (float64 iterates; the volume comes back as float32)
    err = np.max(np.abs(many["volume"] - one["volume"])) / np.max(np.abs(one["volume"]))
    assert err <= 1e-7, f"reconstruct over {split} on {COMM.Get_size()} ranks: {err}"
    err = np.max(np.abs(many["tf"] - one["tf"])) / np.max(np.abs(one["tf"]))
    assert err <= 1e-12, f"reconstruct over {split} on {COMM.Get_size()} ranks, TF: {err}"
    with pytest.raises(ivr.Error, match="split 'rows'"):
        ivr.mpi.reconstruct(ctx, s, targets, split="rows", **options)


def test_ray_list(ctx):
    s, v = scene_of(1), volume()
    rays = []
    for k in range(7):
        rays.append([0.2 * k - 0.6, 0.1, 2.0, 0.05 * k, -0.02, -1.0, 0.0, 10.0])
    s = dict(s, rays=rays)
    del s["cameras"]
    one = ctx.render(s, v)
    close(one, ivr.mpi.render(ctx, s, v), "render of a ray list")
    target = 0.7 * one + 0.1
    l1, g1 = ctx.gradient(s, v, target, wrt=("density", "rays"))
    ln, gn = ivr.mpi.gradient(ctx, s, v, target, wrt=("density", "rays"))
    assert abs(ln - l1) <= 1e-12 * abs(l1)
    close(g1["density"], gn["density"], "ray-list density gradient")
    close(g1["rays"], gn["rays"], "ray-list ray gradient")


def test_view_shares_by_weight():
    assert ivr.view_shares_by(8, [3, 1]) == [(0, 6), (6, 2)]
    assert ivr.view_shares_by(4, [1, 9]) == [(0, 1), (1, 3)]  # (each: the weighted split is 0, 4)
    assert ivr.view_shares_by(4, [1, 9], each=False) == [(0, 0), (0, 4)]
    assert ivr.view_shares_by(2, [1, 5, 9]) == [(0, 1), (1, 1), (2, 0)]
    with pytest.raises(ivr.Error, match=r"shares\[1\]"):
        ivr.view_shares_by(4, [1, 0])


def test_shares_by_weight_equal_one_process(ctx):
    # Unequal shares, one weight a rank (1 : 4 : 7; the last rank takes most views), and the
    # default — each rank's speed, equal on one machine — give one process's results.
    size, s, v = COMM.Get_size(), scene_of(5), volume()
    shares = [1.0 + 3 * r for r in range(size)]
    assert ivr.mpi.rank_weights(ctx) == [ctx.samples_per_second] * size
    one = ctx.render(s, v)
    assert np.array_equal(ivr.mpi.render(ctx, s, v, shares=shares), one), "render by weight"
    lines = ctx.project(s, v)
    close(lines, ivr.mpi.project(ctx, s, v, shares=shares), "projection by weight")
    a = dict(s, model="absorption")
    x1, _ = ctx.tomo(a, lines, iterations=3, grid=v.shape)
    xn, _ = ivr.mpi.tomo(ctx, a, lines, iterations=3, grid=v.shape, shares=shares)
    assert np.max(np.abs(xn.astype(np.float64) - x1)) <= 1e-6 * np.max(np.abs(x1)), "tomo"
    with ivr.Context(precision="f32") as c:
        target = 0.8 * c.render(s, v) + 0.05
        g1 = c.gradient(s, v, target, mode="adjoint", deterministic=True)[1]
        gn = ivr.mpi.gradient(c, s, v, target, mode="adjoint", deterministic=True,
                              shares=shares[::-1])[1]
    assert np.array_equal(g1["density"], gn["density"]), "deterministic density by weight"
    # A batch of 3 over ranks weighted 1 : 1000 (: 1): every rank keeps a view of each batch.
    targets = ctx.render(s, v)
    options = dict(volume=np.zeros_like(v), wrt=("density", "tf"), iterations=4, batch=3,
                   levels=1, init="constant", init_value=0.3, seed=5)
    r1 = ctx.reconstruct(s, targets, **options)
    rn = ivr.mpi.reconstruct(ctx, s, targets, shares=[1.0, 1000.0, 1.0][:size], **options)
    for a, b in zip(rn["history"], r1["history"]):
        assert a["views"] == b["views"] and abs(a["loss"] - b["loss"]) <= 1e-10 * b["loss"], (a, b)
    err = np.max(np.abs(rn["volume"].astype(np.float64) - r1["volume"]))
    assert err <= 1e-6 * np.max(np.abs(r1["volume"])), f"reconstruct by weight: {err}"
    with pytest.raises(ivr.Error, match=f"shares has {size + 1} weights for {size} ranks"):
        ivr.mpi.render(ctx, s, v, shares=[1.0] * (size + 1))


def test_slabs_by_weight_equal_one_process(ctx):
    # Each rank's slab of the 4 planes (3 cells) by weight — 4 : 1 with 2 ranks gives planes 0..2
    # and 2..3 where equal slabs are 0..1 and 1..3 (3 ranks: a cell each, whatever the weights) —
    # gives one process's render, gradients, CGLS and reconstruction, each rank holding its
    # weighted planes; the default (each rank's speed, equal on one machine) the equal slabs.
    size, rank = COMM.Get_size(), COMM.Get_rank()
    s, v = scene_of(3), volume()
    s["integrator"] = {"scheme": "midpoint", "step": 0.5, "min_transmittance": 0}
    shares = [1.0 + 3 * (size - 1 - r) for r in range(size)]
    first, last = ivr.mpi.slab(v.shape[0], shares=shares)
    if size == 2:
        assert (first, last) == ((0, 2), (2, 3))[rank]
    # (the default weights, each rank's speed: equal here, where every rank reads one cost model)
    assert ivr.mpi.slab(v.shape[0], ctx=ctx) == ivr.mpi.slab(v.shape[0], shares=[1.0] * size)
    with pytest.raises(ivr.Error, match="pass ctx="):
        ivr.mpi.slab(v.shape[0])
    one = ctx.render(s, v)
    mine = v[first:last + 1].copy()
    for split in ("slabs", "segments"):
        close(one, ivr.mpi.render(ctx, s, v, split=split, shares=shares), f"render over {split}")
        close(one, ivr.mpi.render(ctx, s, mine, split=split, nz=v.shape[0], shares=shares),
              f"render over {split}, each rank its weighted planes")
    target = 0.8 * one + 0.05
    wrt = ("density", "tf", "background")
    l1, g1 = ctx.gradient(s, v, target, wrt=wrt, mode="adjoint")
    ln, gn = ivr.mpi.gradient(ctx, s, mine, target, wrt=wrt, split="slabs", nz=v.shape[0],
                              shares=shares, gather=False)
    assert abs(ln - l1) <= 1e-12 * abs(l1)
    assert gn["density"].shape == mine.shape
    close(g1["density"][first:last + 1], gn["density"], "density over weighted slabs, its planes")
    close(g1["tf"], gn["tf"], "tf over weighted slabs")
    close(g1["background"], gn["background"], "background over weighted slabs")
    _, gw = ivr.mpi.gradient(ctx, s, v, target, wrt=wrt, split="segments", shares=shares)
    close(g1["density"], gw["density"], "density over weighted segments, gathered")
    a = dict(s, model="absorption")
    lines = ctx.project(a, v)
    x1, _ = ctx.tomo(a, lines, iterations=3, grid=v.shape)
    xn, _ = ivr.mpi.tomo(ctx, a, lines, iterations=3, grid=v.shape, split="slabs", shares=shares)
    assert np.max(np.abs(xn.astype(np.float64) - x1)) <= 1e-6 * np.max(np.abs(x1)), "tomo"
    options = dict(volume=np.full_like(v, 0.3), wrt=("density",), iterations=3, batch=3,
                   levels=1, optimizer="sgd", lr=1.0, seed=5)
    r1 = ctx.reconstruct(s, one, **options)
    rn = ivr.mpi.reconstruct(ctx, s, one, split="slabs", nz=v.shape[0], gather=False,
                             shares=shares, **dict(options, volume=np.full_like(mine, 0.3)))
    assert rn["volume"].shape == mine.shape
    err = np.max(np.abs(rn["volume"] - r1["volume"][first:last + 1]))
    assert err <= 1e-6 * np.max(np.abs(r1["volume"])), f"reconstruct over weighted slabs: {err}"
    with pytest.raises(ivr.Error, match=f"shares has {size + 1} weights for {size} ranks"):
        ivr.mpi.render(ctx, s, v, split="slabs", shares=[1.0] * (size + 1))
    if size == 2:  # the equal split's planes under weights that cut others: named
        equal = ivr.mpi.slab(v.shape[0], shares=[1.0, 1.0])
        with pytest.raises(ivr.Error, match="planes"):
            ivr.mpi.render(ctx, s, v[equal[0]:equal[1] + 1].copy(), split="slabs",
                           nz=v.shape[0], shares=shares)


def test_bad_input_is_refused_clearly(ctx):
    s, v = scene_of(3), volume()
    with pytest.raises(ivr.Error, match="target has 2 rows"):
        ivr.mpi.gradient(ctx, s, v, np.zeros((2, 5, 6, 4), np.float32))
    with pytest.raises(ivr.Error, match="cameras"):
        ivr.mpi.render(ctx, {"model": "absorption"}, v)
    with pytest.raises(ivr.Error, match="lines has 2 rows"):
        ivr.mpi.backproject(ctx, s, np.zeros((2, 5, 6, 1), np.float32))
    with pytest.raises(ivr.Error, match="as an array"):
        ivr.mpi.render(ctx, dict(s, rays={"file": "rays.npy"}), v)
    with pytest.raises(ivr.Error, match="lines has 2 rows"):
        ivr.mpi.tomo(ctx, s, np.zeros((2, 5, 6, 1), np.float32))
    with pytest.raises(ivr.Error, match="split 'rows'"):
        ivr.mpi.tomo(ctx, s, np.zeros((3, 5, 6, 1), np.float32), split="rows")
    with pytest.raises(ivr.Error, match="split 'rows'"):
        ivr.mpi.render(ctx, s, v, split="rows")
    with pytest.raises(ivr.Error, match="split 'segments' \\(views or slabs\\)"):
        ivr.mpi.tomo(ctx, s, np.zeros((3, 5, 6, 1), np.float32), split="segments")
    if COMM.Get_size() > 1:  # more ranks than views
        with pytest.raises(ivr.Error, match="at most one rank each"):
            ivr.mpi.tomo(ctx, scene_of(1), np.zeros((1, 5, 6, 1), np.float32))
