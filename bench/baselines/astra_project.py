"""astra_project.py — the ASTRA Toolbox baseline of ivr-bench's tomo suite: FP3D_CUDA / BP3D_CUDA.

Tasks `project` (the sinogram of a volume, ASTRA's FP3D) and `backproject` (BP3D), parallel beam,
both from host arrays as ASTRA's users call them: astra.create_sino3d_gpu /
astra.create_backprojection3d_gpu, which copy the input into ASTRA's memory, upload it, run the
kernel, download the result and return it as numpy. That whole call is timed, as ivr's
Projector::project / backproject are (from a host vector to a host vector).

The case directory (written by the tomo suite, format "ivr-bench-tomo/1") holds tomo.json,
volume.npy (float32 (nz, ny, nx), x fastest) and lines.npy (float32 (views, H, W): the
back-projection's input, in ivr's ray order). Its cameras are ivr's orthographic cameras, turned
here into ASTRA's parallel3d_vec rows (parallel3d_vectors) and its box into ASTRA's volume window
(volume_geometry); README.md, "ASTRA", gives the conversion. Outputs go back in ivr's order:
`lines` (views, H, W) and `volume` (nz, ny, nx); the sinogram's transposition from ASTRA's
(rows, angles, cols) happens after the clock stops (common.Deferred).

ASTRA's 3D projectors run on CUDA GPUs only: --device cpu, an astra that cannot be imported
(ImportError: not installed, or its CUDA libraries missing) or astra.use_cuda() false all give
"available": false (run.py).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np

from common import Deferred, DeviceUnavailable

TASKS = ("project", "backproject")
CASE_FORMAT = "ivr-bench-tomo/1"
INSTALL_HINT = "bench/baselines/README.md ('ASTRA') shows how to install its wheel on a GPU machine"

astra = None  # imported by version()


def parallel3d_vectors(cameras) -> np.ndarray:
    """ASTRA parallel3d_vec rows (views, 12) for ivr orthographic cameras of one size.

    ivr (kernels/geometry.cl, lib/scene/device_scene.hpp): f = normalize(target − eye), r =
    normalize(f × up), u = r × f, half_h = ortho_height/2, half_w = half_h·W/H; pixel (x, y) is the
    ray eye + sx·half_w·r + sy·half_h·u + t·f with sx = (2x + 1 − W)/W, sy = (H − 2y − 1)/H (row
    0 at the top). ASTRA: pixel (row i, col j) is the line through d + (j + ½ − cols/2)·U +
    (i + ½ − rows/2)·V along the ray direction R. So R = f, d = eye, U = (ortho_height/H)·r (a
    column step; equal to 2·half_w/W) and V = −(ortho_height/H)·u (rows run downwards)."""
    rows = []
    for c in cameras:
        if c.get("projection", "orthographic") != "orthographic":
            raise ValueError("the ASTRA baseline takes orthographic (parallel-beam) cameras only")
        eye, target, up = (np.asarray(c[k], np.float64) for k in ("eye", "target", "up"))
        f = target - eye
        f /= np.linalg.norm(f)
        r = np.cross(f, up)
        r /= np.linalg.norm(r)
        u = np.cross(r, f)
        pitch = float(c["ortho_height"]) / int(c["height"])
        rows.append(np.concatenate([f, eye, pitch * r, -pitch * u]))
    return np.asarray(rows, np.float64)


def volume_geometry(shape, box_min, box_max) -> dict:
    """ASTRA's 3D volume geometry for ivr's grid: what astra.create_vol_geom(ny, nx, nz, x0, x1,
    y0, y1, z0, z1) returns (rows = y, columns = x, slices = z; voxel (x index i) centred at
    WindowMinX + (i + ½)·(WindowMaxX − WindowMinX)/nx, as ivr's box_min + (i + ½)·h, and likewise
    y and z: ASTRA's 3D data (slices, rows, cols) is ivr's (nz, ny, nx), none flipped)."""
    nz, ny, nx = (int(s) for s in shape)
    (x0, y0, z0), (x1, y1, z1) = (map(float, box_min), map(float, box_max))
    return {"GridRowCount": ny, "GridColCount": nx, "GridSliceCount": nz,
            "option": {"WindowMinX": x0, "WindowMaxX": x1, "WindowMinY": y0,
                       "WindowMaxY": y1, "WindowMinZ": z0, "WindowMaxZ": z1}}


def projection_geometry(cameras) -> dict:
    """What astra.create_proj_geom('parallel3d_vec', H, W, vectors) returns."""
    sizes = {(int(c["width"]), int(c["height"])) for c in cameras}
    if len(sizes) != 1:
        raise ValueError("the ASTRA baseline needs every camera the same size")
    (width, height), = sizes
    return {"type": "parallel3d_vec", "DetectorRowCount": height, "DetectorColCount": width,
            "Vectors": parallel3d_vectors(cameras)}


def to_sinogram(lines: np.ndarray) -> np.ndarray:
    """ivr's (views, H, W) → ASTRA's (rows, angles, cols), contiguous."""
    return np.ascontiguousarray(np.asarray(lines, np.float32).transpose(1, 0, 2))


def from_sinogram(sino: np.ndarray) -> np.ndarray:
    """ASTRA's (rows, angles, cols) → ivr's (views, H, W), contiguous."""
    return np.ascontiguousarray(np.asarray(sino).transpose(1, 0, 2))


@dataclass
class TomoCase:
    volume: np.ndarray  # (nz, ny, nx) float32
    lines: np.ndarray  # (views, H, W) float32, ivr's ray order
    vol_geom: dict
    proj_geom: dict


def load_case(case_dir: str) -> TomoCase:
    with open(os.path.join(case_dir, "tomo.json")) as f:
        doc = json.load(f)
    if doc.get("format") != CASE_FORMAT:
        raise ValueError(f"{case_dir}: format {doc.get('format')!r}, expected {CASE_FORMAT!r}")
    volume = np.ascontiguousarray(np.load(os.path.join(case_dir, doc["volume"])), np.float32)
    lines = np.load(os.path.join(case_dir, doc["lines"])).astype(np.float32, copy=False)
    proj_geom = projection_geometry(doc["cameras"])
    expected = (len(doc["cameras"]), proj_geom["DetectorRowCount"], proj_geom["DetectorColCount"])
    if volume.ndim != 3 or lines.shape != expected:
        raise ValueError(f"{case_dir}: volume {volume.shape}, lines {lines.shape} "
                         f"(expected (nz, ny, nx) and {expected})")
    return TomoCase(volume, lines, volume_geometry(volume.shape, doc["box_min"], doc["box_max"]),
                    proj_geom)


def case_fields(case: TomoCase) -> dict:
    """run.py's size fields of a case."""
    return {"voxels": int(case.volume.size), "rays": int(case.lines.size)}


def version(threads: int, device: str = "cpu") -> str:
    """Imports astra (ImportError when missing or its CUDA libraries are not found);
    DeviceUnavailable unless `device` is "gpu" and ASTRA sees a CUDA device. `threads` unused."""
    global astra
    import astra as _astra

    astra = _astra
    if device != "gpu":
        raise DeviceUnavailable("ASTRA's 3D projectors (FP3D_CUDA, BP3D_CUDA) run on CUDA GPUs "
                                "only; ivr-bench runs it beside a GPU device")
    if not astra.use_cuda():
        raise DeviceUnavailable(f"astra {astra.__version__}: astra.use_cuda() is false "
                                "(no CUDA device or driver)")
    return f"astra {astra.__version__}"


def device_name(device: str = "gpu") -> str:
    return str(astra.get_gpu_info())


def prepare(task: str, case: TomoCase, device: str = "gpu"):
    """The timed call: the user's one-line ASTRA call on host arrays, its data object freed.
    Inputs are in ASTRA's layouts already (a user holds them so); outputs in ivr's order."""
    if task == "project":
        volume = case.volume

        def call():
            sino_id, sino = astra.create_sino3d_gpu(volume, case.proj_geom, case.vol_geom)
            astra.data3d.delete(sino_id)
            return {"lines": Deferred(lambda: from_sinogram(sino))}
    elif task == "backproject":
        sino = to_sinogram(case.lines)

        def call():
            vol_id, vol = astra.create_backprojection3d_gpu(sino, case.proj_geom, case.vol_geom)
            astra.data3d.delete(vol_id)
            return {"volume": vol}
    else:
        raise ValueError(f"astra: unknown task {task!r} (known: {', '.join(TASKS)})")
    return call
