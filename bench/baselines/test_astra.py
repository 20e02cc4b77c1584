"""test_astra.py — the ASTRA baseline's geometry conversion and its run.py paths (pytest).

    .venv-bench/bin/python -m pytest bench/baselines/test_astra.py

No GPU is needed: the ivr camera → parallel3d_vec conversion is checked in numpy against the
cameras' pixel rays written out here from ivr's definition (kernels/geometry.cl,
lib/scene/device_scene.hpp) and against ASTRA's own parallel3d geometry; run.py's unavailable paths
(astra missing, astra without CUDA, --device cpu) and its end-to-end plumbing run with stand-in
`astra` packages put first on PYTHONPATH. Where the real astra imports, its geometry
constructors are compared too (those tests skip elsewhere); its CUDA projectors are not run here.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import astra_project as ap  # noqa: E402

# Off-centre targets, tilted up vectors, non-square images.
CAMERAS = [
    {"eye": [1.7, -0.4, 0.9], "target": [0.05, 0.1, -0.02], "up": [0.1, 0.2, 1.0],
     "projection": "orthographic", "ortho_height": 1.3, "width": 7, "height": 5},
    {"eye": [-0.3, 2.1, -0.6], "target": [0.0, -0.05, 0.1], "up": [1.0, 0.0, 0.3],
     "projection": "orthographic", "ortho_height": 0.9, "width": 7, "height": 5},
    # An orbit camera as the tomo suite's, tilted a little so that no ray runs along a box face
    # (where the zero-border interpolant of ASTRA and the stand-in gives half the chord).
    {"eye": [2 * math.cos(0.7), 2 * math.sin(0.7), 0.15], "target": [0, 0, 0], "up": [0, 0, 1],
     "projection": "orthographic", "ortho_height": 1.0, "width": 7, "height": 5},
]


def ivr_pixel_rays(cam):
    """Origins (H, W, 3) and unit direction of an ivr orthographic camera's pixel rays, as ivr
    defines them: origin = eye + sx·(h/2)(W/H)·right + sy·(h/2)·up, sx = (2x + 1 − W)/W,
    sy = (H − 2y − 1)/H, direction forward."""
    eye, target, up = (np.asarray(cam[k], float) for k in ("eye", "target", "up"))
    W, H, h = cam["width"], cam["height"], cam["ortho_height"]
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, up) / np.linalg.norm(np.cross(fwd, up))
    upv = np.cross(right, fwd)
    sx = (2 * np.arange(W) + 1 - W) / W
    sy = (H - 2 * np.arange(H) - 1) / H
    origin = (eye + sx[None, :, None] * (h / 2) * (W / H) * right
              + sy[:, None, None] * (h / 2) * upv)
    return origin, fwd


def astra_pixel_lines(vec, rows, cols):
    """Pixel-centre points (rows, cols, 3) and direction of one parallel3d_vec row, as ASTRA
    defines them (ParallelVecProjectionGeometry3D: corner = d − rows/2·v − cols/2·u, pixel (i, j)
    centred at corner + (j + ½)·u + (i + ½)·v)."""
    ray, d, u, v = vec[0:3], vec[3:6], vec[6:9], vec[9:12]
    j, i = np.arange(cols), np.arange(rows)
    centre = (d + (j[None, :, None] + 0.5 - cols / 2) * u + (i[:, None, None] + 0.5 - rows / 2) * v)
    return centre, ray


def test_vectors_reproduce_ivr_pixel_rays():
    vectors = ap.parallel3d_vectors(CAMERAS)
    assert vectors.shape == (len(CAMERAS), 12)
    for cam, vec in zip(CAMERAS, vectors):
        origin, fwd = ivr_pixel_rays(cam)
        centre, ray = astra_pixel_lines(vec, cam["height"], cam["width"])
        # The same direction (up to scale and sign: a line), and every ASTRA pixel centre on the
        # ivr ray of the same (y, x): the perpendicular offset vanishes.
        np.testing.assert_allclose(np.cross(ray, fwd), 0, atol=1e-12)
        off = centre - origin
        off -= (off @ fwd)[..., None] * fwd
        np.testing.assert_allclose(off, 0, atol=1e-12)
        # Square pixels of pitch ortho_height/H, u along the image's x, v down its rows.
        pitch = cam["ortho_height"] / cam["height"]
        np.testing.assert_allclose(np.linalg.norm(vec[6:9]), pitch, rtol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(vec[9:12]), pitch, rtol=1e-12)
        np.testing.assert_allclose(vec[6:9] @ vec[9:12], 0, atol=1e-14)


def tomo_orbit(views, n):
    """The tomo suite's parallel cameras (bench/bench_scene.hpp, tomo_scene): eye at distance 2
    on the z = 0 circle, half a turn, looking at the origin, up +z, ortho_height 1, n² pixels."""
    return [{"eye": [2 * math.cos(math.pi * k / views), 2 * math.sin(math.pi * k / views), 0.0],
             "target": [0, 0, 0], "up": [0, 0, 1], "projection": "orthographic",
             "ortho_height": 1.0, "width": n, "height": n} for k in range(views)]


def astra_parallel3d_vectors(angles, spacing):
    """ASTRA's own 'parallel3d' geometry as vectors (astra.functions.geom_2vec, written out)."""
    s, c, z = np.sin(angles), np.cos(angles), np.zeros_like(angles)
    return np.stack([s, -c, z, z, z, z, c * spacing, s * spacing, z, z, z, z + spacing], axis=1)


def _same_lines(vec_a, vec_b, rows, cols):
    ca, ra = astra_pixel_lines(vec_a, rows, cols)
    cb, rb = astra_pixel_lines(vec_b, rows, cols)
    r = rb / np.linalg.norm(rb)
    np.testing.assert_allclose(np.cross(ra, r), 0, atol=1e-12)
    off = ca - cb
    off -= (off @ r)[..., None] * r
    np.testing.assert_allclose(off, 0, atol=1e-12)


def test_tomo_orbit_is_astra_parallel3d_turned_a_quarter():
    """The suite's orbit is ASTRA's standard parallel3d scan at angles a + π/2 (detector pitch
    1/n) with the detector rows flipped (ivr's row 0 is the top, ASTRA's v points up): the same
    lines, pixel for pixel."""
    n, views = 6, 5
    ours = ap.parallel3d_vectors(tomo_orbit(views, n))
    theirs = astra_parallel3d_vectors(np.pi * np.arange(views) / views + np.pi / 2, 1.0 / n)
    theirs[:, 9:12] *= -1  # flip the rows
    for a, b in zip(ours, theirs):
        _same_lines(a, b, n, n)


def test_volume_geometry_and_layouts():
    g = ap.volume_geometry((4, 5, 6), [-0.5, -0.4, -0.3], [0.7, 0.6, 0.5])
    assert (g["GridSliceCount"], g["GridRowCount"], g["GridColCount"]) == (4, 5, 6)
    o = g["option"]
    assert (o["WindowMinX"], o["WindowMaxX"], o["WindowMinY"], o["WindowMaxY"],
            o["WindowMinZ"], o["WindowMaxZ"]) == (-0.5, 0.7, -0.4, 0.6, -0.3, 0.5)
    lines = np.random.default_rng(1).random((3, 5, 7), dtype=np.float32)  # (views, H, W)
    sino = ap.to_sinogram(lines)
    assert sino.shape == (5, 3, 7) and sino.flags.c_contiguous and sino[4, 2, 6] == lines[2, 4, 6]
    np.testing.assert_array_equal(ap.from_sinogram(sino), lines)
    with pytest.raises(ValueError):
        ap.parallel3d_vectors([dict(CAMERAS[0], projection="perspective")])
    with pytest.raises(ValueError):
        ap.projection_geometry([CAMERAS[0], dict(CAMERAS[1], width=8)])


def _real_astra():
    try:
        import astra
    except ImportError:  # not installed, or its CUDA runtime libraries are not on the path
        pytest.skip("astra is not importable here")
    if getattr(astra, "STANDIN", False):
        pytest.skip("a stand-in astra is on the path")
    return astra


def test_real_astra_accepts_the_geometry():
    """With ASTRA importable: its constructors give our dicts, its geom_2vec gives the parallel3d
    vectors written out above, and its data objects take the shapes we hand it (CPU-side: no GPU
    needed)."""
    astra = _real_astra()
    shape, box = (4, 5, 6), ([-0.5, -0.4, -0.3], [0.7, 0.6, 0.5])
    ours = ap.volume_geometry(shape, *box)
    theirs = astra.create_vol_geom(5, 6, 4, -0.5, 0.7, -0.4, 0.6, -0.3, 0.5)
    assert {k: theirs[k] for k in ours if k != "option"} == {k: v for k, v in ours.items()
                                                          if k != "option"}
    assert {k: theirs["option"][k] for k in ours["option"]} == ours["option"]
    angles = np.linspace(0, 2, 5)
    vec = astra.functions.geom_2vec(astra.create_proj_geom("parallel3d", 0.2, 0.2, 5, 7, angles))
    np.testing.assert_allclose(vec["Vectors"], astra_parallel3d_vectors(angles, 0.2), atol=1e-15)
    proj = ap.projection_geometry(CAMERAS)
    pg = astra.create_proj_geom("parallel3d_vec", 5, 7, proj["Vectors"])
    assert {k: pg[k] for k in ("type", "DetectorRowCount", "DetectorColCount")} == {
        k: proj[k] for k in ("type", "DetectorRowCount", "DetectorColCount")}
    sino_id = astra.data3d.create("-sino", proj, ap.to_sinogram(np.ones((3, 5, 7), np.float32)))
    vol_id = astra.data3d.create("-vol", ours, np.ones(shape, np.float32))
    try:
        assert astra.data3d.get(sino_id).shape == (5, 3, 7)
        assert astra.data3d.get(vol_id).shape == shape
    finally:
        astra.data3d.delete([sino_id, vol_id])


# -- run.py with stand-in astra packages --------------------------------------------------------

# A numpy astra with ASTRA's conventions (README "ASTRA"): FP as ASTRA's par3d kernel computes it
# (trilinear samples, zero outside the volume, on the planes through voxel centres across the
# ray's dominant axis, each weighted by the world length between planes), BP as its exact
# adjoint. STANDIN_CUDA=0 makes use_cuda() false.
STANDIN = '''
import os
import numpy as np
STANDIN = True
__version__ = "0.0-standin"
_store = {}
class data3d:
    @staticmethod
    def delete(i):
        for k in (i if isinstance(i, list) else [i]):
            _store.pop(k, None)
def use_cuda():
    return os.environ.get("STANDIN_CUDA", "1") == "1"
def get_gpu_info(idx=-1):
    return "GPU #0: stand-in"
def _weights(shape, vol_geom, proj_geom):
    nz, ny, nx = shape
    o = vol_geom["option"]
    lo = np.array([o["WindowMinX"], o["WindowMinY"], o["WindowMinZ"]])
    hi = np.array([o["WindowMaxX"], o["WindowMaxY"], o["WindowMaxZ"]])
    h = (hi - lo) / [nx, ny, nz]
    rows, cols = proj_geom["DetectorRowCount"], proj_geom["DetectorColCount"]
    V = proj_geom["Vectors"]
    out = []  # (flat sinogram index, flat voxel index, weight)
    for k, vec in enumerate(V):
        ray, d, u, v = vec[0:3], vec[3:6], vec[6:9], vec[9:12]
        i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        p = d + (j[..., None] + 0.5 - cols / 2) * u + (i[..., None] + 0.5 - rows / 2) * v
        q = (p - lo) / h - 0.5  # voxel-index coordinates, centres at integers
        rd = ray / h
        a = int(np.argmax(np.abs(rd)))
        step = h[a] / abs(ray[a] / np.linalg.norm(ray))
        sino_index = (i * len(V) + k) * cols + j
        for s in range(int([nx, ny, nz][a])):
            pos = q + ((s - q[..., a]) / rd[a])[..., None] * rd
            base = np.floor(pos).astype(int)
            f = pos - base
            for corner in range(8):
                c = np.array([(corner >> b) & 1 for b in range(3)])
                idx = base + c
                w = np.prod(np.where(c == 1, f, 1 - f), axis=-1) * step
                ok = np.all((idx >= 0) & (idx < [nx, ny, nz]), axis=-1) & (w != 0)
                voxel = (idx[..., 2] * ny + idx[..., 1]) * nx + idx[..., 0]
                out.append((sino_index[ok], voxel[ok], w[ok]))
    return [np.concatenate(x) for x in zip(*out)]
def _new(a):
    key = len(_store) + 1 + max(_store, default=0)
    _store[key] = a
    return key, a
def create_sino3d_gpu(data, proj_geom, vol_geom, returnData=True, gpuIndex=None):
    assert data.dtype == np.float32 and data.flags.c_contiguous
    rows, cols = proj_geom["DetectorRowCount"], proj_geom["DetectorColCount"]
    si, vi, w = _weights(data.shape, vol_geom, proj_geom)
    sino = np.zeros(rows * len(proj_geom["Vectors"]) * cols)
    np.add.at(sino, si, w * data.ravel()[vi])
    return _new(sino.reshape(rows, -1, cols).astype(np.float32))
def create_backprojection3d_gpu(data, proj_geom, vol_geom, returnData=True):
    assert data.dtype == np.float32 and data.flags.c_contiguous
    shape = (vol_geom["GridSliceCount"], vol_geom["GridRowCount"], vol_geom["GridColCount"])
    si, vi, w = _weights(shape, vol_geom, proj_geom)
    vol = np.zeros(int(np.prod(shape)))
    np.add.at(vol, vi, w * data.ravel()[si])
    return _new(vol.reshape(shape).astype(np.float32))
'''

BOX = ([-0.45, -0.5, -0.4], [0.55, 0.45, 0.5])  # off-centre, not a cube: flips would show


def make_tomo_case(directory, volume, lines, cameras=CAMERAS):
    os.makedirs(directory, exist_ok=True)
    np.save(os.path.join(directory, "volume.npy"), volume.astype(np.float32))
    np.save(os.path.join(directory, "lines.npy"), lines.astype(np.float32))
    doc = {"format": ap.CASE_FORMAT, "volume": "volume.npy", "lines": "lines.npy",
           "box_min": BOX[0], "box_max": BOX[1], "cameras": cameras}
    with open(os.path.join(directory, "tomo.json"), "w") as f:
        json.dump(doc, f, indent=1)
    return str(directory)


def _standin(tmp_path, source=STANDIN):
    pkg = tmp_path / "standin" / "astra"
    pkg.mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text(textwrap.dedent(source))
    return str(pkg.parent)


def _run(tmp_path, case, task, device="gpu", env_extra=None, name="result"):
    out = tmp_path / f"{name}.json"
    env = dict(os.environ, **(env_extra or {}))
    p = subprocess.run([sys.executable, os.path.join(HERE, "run.py"), "--framework", "astra",
                        "--task", task, "--case", case, "--out", str(out), "--budget", "0",
                        "--min-repeats", "2", "--device", device],
                       capture_output=True, text=True, env=env, timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    return json.loads(out.read_text())


@pytest.fixture()
def tiny_case(tmp_path):
    rng = np.random.default_rng(3)
    return make_tomo_case(tmp_path / "case", rng.random((4, 5, 6)), rng.random((3, 5, 7)))


def test_run_astra_missing(tmp_path, tiny_case):
    """An astra that cannot be imported (as with its CUDA libraries missing): available false,
    exit 0, with the install hint."""
    shadow = tmp_path / "shadow" / "astra"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text("raise ImportError('libcufft.so.11: cannot open')\n")
    doc = _run(tmp_path, tiny_case, "project", env_extra={"PYTHONPATH": str(shadow.parent)})
    assert doc["available"] is False and "not installed" in doc["note"], doc
    assert "README" in doc["note"] and "outputs" not in doc, doc


def test_run_astra_without_cuda_or_gpu(tmp_path, tiny_case):
    """astra imports but use_cuda() is false, or --device cpu: available false, exit 0."""
    path = {"PYTHONPATH": _standin(tmp_path)}
    doc = _run(tmp_path, tiny_case, "backproject", env_extra=dict(path, STANDIN_CUDA="0"))
    assert doc["available"] is False and "use_cuda() is false" in doc["note"], doc
    doc = _run(tmp_path, tiny_case, "project", device="cpu", env_extra=path)
    assert doc["available"] is False and "CUDA GPUs only" in doc["note"], doc
    assert doc["device"] == "cpu"


def test_run_astra_task_checked(tmp_path, tiny_case):
    p = subprocess.run([sys.executable, os.path.join(HERE, "run.py"), "--framework", "astra",
                        "--task", "render", "--case", tiny_case, "--out", str(tmp_path / "r.json")],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "does the tasks project, backproject" in p.stderr


def _chords(cameras):
    """Each ivr pixel ray's chord through BOX (slabs), in ivr's order (views, H, W)."""
    out = []
    lo, hi = (np.asarray(b, float) for b in BOX)
    for cam in cameras:
        origin, fwd = ivr_pixel_rays(cam)
        t0, t1 = np.full(origin.shape[:2], -np.inf), np.full(origin.shape[:2], np.inf)
        for a in range(3):
            o = origin[..., a]
            if fwd[a] == 0:  # parallel to the slab: inside it (closed) or a miss
                t1 = np.where((o < lo[a]) | (o > hi[a]), -np.inf, t1)
                continue
            ta, tb = (lo[a] - o) / fwd[a], (hi[a] - o) / fwd[a]
            t0, t1 = np.maximum(t0, np.minimum(ta, tb)), np.minimum(t1, np.maximum(ta, tb))
        out.append(np.maximum(t1 - t0, 0))
    return np.stack(out)


def test_run_astra_standin_end_to_end(tmp_path):
    """Through run.py with the stand-in: outputs come back in ivr's order and match ivr's rays —
    a constant volume projects to each ivr ray's chord through the box (up to the border
    voxels' half-cells), a single hot voxel lights the ivr pixels whose rays pass nearest, and
    project / backproject are each other's transpose through the layout conversions."""
    nz, ny, nx = 6, 7, 8
    path = {"PYTHONPATH": _standin(tmp_path)}
    lines = np.random.default_rng(5).random((len(CAMERAS), 5, 7))
    case = make_tomo_case(tmp_path / "ones", np.ones((nz, ny, nx)), lines)
    doc = _run(tmp_path, case, "project", env_extra=path)
    assert doc["available"] and doc["ok"], doc
    assert doc["version"] == "astra 0.0-standin" and doc["device_name"] == "GPU #0: stand-in"
    assert len(doc["times_s"]) >= 2 and doc["first_call_s"] > 0, doc
    assert doc["voxels"] == nx * ny * nz and doc["rays"] == lines.size, doc
    got = np.load(os.path.join(case, doc["outputs"]["lines"]))
    assert got.shape == lines.shape and got.dtype == np.float32
    chords = _chords(CAMERAS)
    # The stand-in (like ASTRA) integrates from the first to the last centre plane, and its
    # zero-border interpolant reaches half a voxel past the box: within ~2 half-voxels.
    hit = chords > 0.2
    assert hit.sum() > 20 and (~hit).sum() > 5  # some rays miss or graze: orientation shows
    np.testing.assert_allclose(got[hit], chords[hit], atol=0.25)

    # One hot voxel: the brightest pixel of each view is where ivr's rays pass nearest its centre.
    volume = np.zeros((nz, ny, nx))
    zi, yi, xi = 4, 2, 5
    volume[zi, yi, xi] = 1
    lo, hi = (np.asarray(b, float) for b in BOX)
    centre = lo + (np.array([xi, yi, zi]) + 0.5) * (hi - lo) / [nx, ny, nz]
    case = make_tomo_case(tmp_path / "hot", volume, lines)
    doc = _run(tmp_path, case, "project", env_extra=path, name="hot")
    got = np.load(os.path.join(case, doc["outputs"]["lines"]))
    for view, cam in enumerate(CAMERAS):
        origin, fwd = ivr_pixel_rays(cam)
        off = centre - origin
        dist = np.linalg.norm(off - (off @ fwd)[..., None] * fwd, axis=-1)
        assert np.unravel_index(np.argmax(got[view]), dist.shape) == np.unravel_index(
            np.argmin(dist), dist.shape), view

    # ⟨FP x, y⟩ = ⟨x, BP y⟩ in ivr's layouts.
    rng = np.random.default_rng(9)
    x = rng.random((nz, ny, nx)).astype(np.float32)
    case = make_tomo_case(tmp_path / "dot", x, lines)
    fp = _run(tmp_path, case, "project", env_extra=path, name="fp")
    bp = _run(tmp_path, case, "backproject", env_extra=path, name="bp")
    fx = np.load(os.path.join(case, fp["outputs"]["lines"])).astype(float)
    bty = np.load(os.path.join(case, bp["outputs"]["volume"])).astype(float)
    assert bty.shape == x.shape
    lhs, rhs = (fx * lines.astype(np.float32)).sum(), (x * bty).sum()
    assert math.isclose(lhs, rhs, rel_tol=1e-5), (lhs, rhs)
