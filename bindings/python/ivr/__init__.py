"""ivr — differentiable volume rendering on OpenCL, from Python (ctypes over ivr's C API).

    import ivr, numpy as np
    ctx = ivr.Context(device=None, precision="f32")
    image = ctx.render(scene, volume)                  # (views, H, W, C) float32
    loss, grads = ctx.gradient(scene, volume, target, wrt=("density", "tf"), mode="auto")
    J = ctx.jacobian(scene, volume, wrt=("camera",))   # (views, H, W, C, P)
    p = ctx.project(scene, volume)                     # line integrals (views, H, W, 1)
    x, history = ctx.tomo(scene, p, solver="cgls", iterations=50)   # (Z, Y, X)
    out = ctx.reconstruct(scene, images, wrt=("density",))  # out["volume"], out["history"]
    best = ctx.viewpoint(scene, view=0)                # best["camera"], best["entropy_best"]

    # A session keeps the scene on the device; results are DeviceArrays, read back when asked.
    with ivr.Session(ctx, scene, volume) as s:
        s.set_target(target)
        opt = ivr.DensityOptimizer(s, "adam", lr=0.02)
        for _ in range(50):
            l, g = s.gradient(wrt=("density",))         # DeviceArrays; float(l) reads the loss
            s.step(opt, g["density"])                  # densities updated in place (>= 0)
        v = s.volume.numpy()                           # (Z, Y, X); s.render().numpy() images

`scene` is a dict with the JSON fields of docs/design.md (or JSON text); `volume`, a (Z, Y, X) array
of float32/float64/uint8/uint16, replaces the scene's own volume (which may then be left out).
Errors raise ivr.Error with the C status name and the library's message.
"""
import ctypes
import json
import os
import threading

import numpy as np

from . import _capi

__all__ = ["Error", "Context", "devices", "version", "loss", "project", "backproject", "tomo",
           "lines_from_intensities", "phantom", "reconstruct", "viewpoint", "image_entropy",
           "psnr", "Session", "DeviceArray", "DensityOptimizer"]

_lib = None
_lib_lock = threading.Lock()


def _library():
    global _lib
    with _lib_lock:
        if _lib is None:
            _lib = _capi.load()
        return _lib


class Error(RuntimeError):
    """An ivr call failed: `status` is the C status name (e.g. "IVR_ERROR_INVALID_ARGUMENT")."""

    def __init__(self, status, message):
        super().__init__(f"{status}: {message}")
        self.status = status
        self.message = message


def _check(status):
    if status != 0:
        lib = _library()
        raise Error(lib.ivr_status_string(status).decode(), lib.ivr_last_error().decode())


def _volume_array(volume):
    """`volume` as contiguous (Z, Y, X) host memory of a dtype the library takes."""
    v = np.asarray(volume)
    if v.ndim != 3:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"volume must have shape (Z, Y, X), got {v.shape}")
    if v.dtype not in _DTYPES:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"volume dtype must be float32, float64, uint8 or uint16, got {v.dtype}")
    return np.ascontiguousarray(v)


def _slab_of(split):
    """(nz, rank, ranks, weights) where a split call's volume is that rank's slab of nz planes (cut
    by the ranks' weights, None: equal), else None."""
    if split is None or split[4] is None:  # ((split, rank, ranks, add, nz, weights))
        return None
    return (split[4], split[1], split[2], split[5])


class _Owned:
    """Holds one C handle (self._handle) and releases it with the C function named by
    `_release` on close(), at garbage collection or on leaving a with-block; `_what` names it
    in the error a closed one raises."""
    _release = ""
    _what = "handle"

    def close(self):
        """Releases the handle now (also done when the object is garbage-collected)."""
        if getattr(self, "_handle", None):
            getattr(self._lib, self._release)(self._handle)
            self._handle = None

    def __del__(self):
        self.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _live(self):
        if not getattr(self, "_handle", None):
            raise Error("IVR_ERROR_INVALID_HANDLE", f"the {self._what} is closed")
        return self._handle


def version():
    """The library's version as (major, minor, patch)."""
    v = _library().ivr_version()
    return (v // 10000, v // 100 % 100, v % 100)


def devices():
    """Every OpenCL device as a list of dicts (the fields of `ivr devices --json`)."""
    lib = _library()
    needed = ctypes.c_size_t(0)
    _check(lib.ivr_devices_json(None, 0, ctypes.byref(needed)))
    buf = ctypes.create_string_buffer(needed.value)
    _check(lib.ivr_devices_json(buf, needed.value, None))
    return json.loads(buf.value.decode())["devices"]


def loss(image, target, kind="mse"):
    """The loss (mean over every element) of `image` against `target` (same shape)."""
    a = np.ascontiguousarray(image, dtype=np.float32)
    b = np.ascontiguousarray(target, dtype=np.float32)
    if a.shape != b.shape:
        raise Error("IVR_ERROR_INVALID_ARGUMENT", f"image {a.shape} and target {b.shape} differ")
    value = ctypes.c_double()
    fp = ctypes.POINTER(ctypes.c_float)
    _check(_library().ivr_image_loss(a.ctypes.data_as(fp), b.ctypes.data_as(fp), a.size,
                                     _choice(_LOSSES, kind, "loss"), ctypes.byref(value)))
    return value.value


_DTYPES = {np.dtype(np.float32): 0, np.dtype(np.float64): 1, np.dtype(np.uint8): 2,
           np.dtype(np.uint16): 3}
_PRECISIONS = {"f32": 0, "f64": 1}
_MODES = {"auto": 0, "forward": 1, "adjoint": 2}
_MODE_NAMES = {1: "forward", 2: "adjoint"}
_LOSSES = {"mse": 0, "l1": 1, "dot": 2}  # dot: sum(target * image), a vector-Jacobian product
_SOLVERS = {"cgls": 0, "sirt": 1, "lsqr": 2}
_FLOAT_P = ctypes.POINTER(ctypes.c_float)


def phantom(name, n, seed=1, supersample=1):
    """A tomography test volume, float32 (n, n, n) sampled at the voxel centres of [-1, 1]^3:
    "shepp-logan" (3D Shepp-Logan of Kak & Slaney) or "ellipsoids" (10 random ellipsoids from
    `seed`, the same on every platform). supersample s > 1: each voxel the mean of s^3 samples at
    its sub-cell centres (the cell average)."""
    if not 1 <= int(n) <= 1024:
        raise Error("IVR_ERROR_INVALID_ARGUMENT", f"phantom: n = {n} (1 .. 1024)")
    out = np.empty((int(n),) * 3, dtype=np.float32)
    _check(_library().ivr_phantom(name.encode(), int(n), int(seed), int(supersample),
                                  out.ctypes.data_as(_FLOAT_P),
                                  out.size))
    return out


def image_entropy(image, background=1.0):
    """Normalised entropy in [0, 1] of view 0 of `image` ((views, H, W, C) or (H, W, C), C = 1
    or 4): pixel brightness q (mean of R, G, B; absorption 1 - I / background) + 1e-6,
    p = q / sum q, -sum p ln p / ln(pixels). What Context.viewpoint maximises."""
    from . import _reconstruct
    return _reconstruct.image_entropy(_library(), image, background)


def psnr(image, reference):
    """Peak signal-to-noise ratio with peak 1: 10 log10(1 / mean((image - reference)^2)), over
    every element (same shapes); inf when they are equal."""
    from . import _reconstruct
    return _reconstruct.psnr(_library(), image, reference)


def _choice(table, value, what):
    if value not in table:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"{what} must be one of {', '.join(map(str, table))}, got {value!r}")
    return table[value]


def _sum_fn(add, failure):
    """An ivr_sum_fn calling add(a) on the library's doubles (summing them over the workers in
    place); an exception is kept in `failure` and the call reports failure."""
    def summed(values, count, _user):
        try:
            add(np.ctypeslib.as_array(values, shape=(count,)))
            return 1
        except BaseException as error:  # noqa: BLE001 — re-raised once the library returns
            failure.append(error)
            return 0
    return _capi.SUM_FN(summed)


def _optional_choice(table, value, what):
    """_choice, or None (the library's default) for None."""
    return None if value is None else _choice(table, value, what)


def ray_array(rays):
    """`rays` as the (R, 8) or (R, 6) float64 C-ordered array a ray list is made from
    (docs/design.md, "Ray lists": ox oy oz dx dy dz t_start t_end, or start and end points)."""
    a = np.ascontiguousarray(rays, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] not in (6, 8):
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"rays: expected shape (rays, 8) or (rays, 6), got {a.shape}")
    if a.shape[0] == 0:
        raise Error("IVR_ERROR_INVALID_ARGUMENT", "rays: no rays")
    return a


class Context(_Owned):
    """A device and its compiled kernels. Use one context per thread; contexts on different
    threads run concurrently."""
    _release, _what = "ivr_context_release", "context"

    def __init__(self, device=None, precision="f32"):
        self._lib = _library()
        self.precision = precision
        _choice(_PRECISIONS, precision, "precision")
        handle = _capi.HANDLE()
        _check(self._lib.ivr_context_create(device.encode() if device else None,
                                            ctypes.byref(handle)))
        self._handle = handle

    @property
    def device(self):
        """The device's name."""
        name = ctypes.c_char_p()
        _check(self._lib.ivr_context_device_name(self._live(), ctypes.byref(name)))
        return name.value.decode()

    @property
    def samples_per_second(self):
        """The device's render speed from its cost model (`ivr calibrate`'s file, else estimated
        from its size): the default weight of its share of the views (ivr.mpi)."""
        speed = ctypes.c_double()
        _check(self._lib.ivr_context_samples_per_second(self._live(), ctypes.byref(speed)))
        return speed.value

    def load_volume(self, source, base_dir=None):
        """A volume as float32 (Z, Y, X) densities, read as a scene would: `source` is a path
        or docs/design.md's "volume" object (a dict: {"file": ..., "dims": ..., "type": ...} or
        {"synthetic": "sphere", "dims": [X, Y, Z]}); relative paths resolve against base_dir."""
        obj = {"file": os.fspath(source)} if isinstance(source, (str, os.PathLike)) else source
        handle = _capi.HANDLE()
        _check(self._lib.ivr_volume_from_json(self._live(), json.dumps(obj).encode(),
                                              base_dir.encode() if base_dir else None,
                                              ctypes.byref(handle)))
        try:
            shape = (ctypes.c_int64 * 3)()
            _check(self._lib.ivr_volume_shape(handle, shape))
            out = np.empty(tuple(shape), dtype=np.float32)
            _check(self._lib.ivr_volume_data(
                handle, out.ctypes.data_as(ctypes.POINTER(ctypes.c_float)), out.size))
            return out
        finally:
            self._lib.ivr_volume_release(handle)

    # One scene handle for the duration of a call.
    def _scene(self, scene, volume, base_dir, slab=None):
        # slab (nz, rank, ranks, weights): `volume` is that worker's planes of a volume of nz
        # planes, the workers' slabs cut by the weights (None: equal).
        rays = None
        if isinstance(scene, dict) and "rays" in scene and not isinstance(scene["rays"], dict):
            # A ray list in memory: the JSON holds a stand-in ray (so that the scene is whole),
            # ivr_scene_set_rays then checks and takes every row without a trip through text.
            rays = ray_array(scene["rays"])
            scene = dict(scene, rays=[[0, 0, 0, 1, 0, 0, 0, 0]])
        text = scene if isinstance(scene, str) else json.dumps(scene)
        handle = _capi.HANDLE()
        _check(self._lib.ivr_scene_from_json(self._live(), text.encode(),
                                             base_dir.encode() if base_dir else None,
                                             ctypes.byref(handle)))
        try:
            if rays is not None:
                _check(self._lib.ivr_scene_set_rays(
                    handle, rays.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), rays.shape[0],
                    rays.shape[1]))
            if volume is not None:
                v = _volume_array(volume)
                shape = (ctypes.c_int64 * 3)(*v.shape)
                if slab is None:
                    _check(self._lib.ivr_scene_set_volume(
                        handle, v.ctypes.data_as(ctypes.c_void_p), _DTYPES[v.dtype], shape))
                else:
                    nz, rank, ranks, weights = slab
                    _check(self._lib.ivr_scene_set_volume_slab_weighted(
                        handle, v.ctypes.data_as(ctypes.c_void_p), _DTYPES[v.dtype], shape,
                        nz, rank, ranks, _doubles(weights)))
        except BaseException:
            self._lib.ivr_scene_release(handle)
            raise
        return handle

    def _image_shape(self, scene_handle):
        """(views, H, W, C); a ray list's (rays, C)."""
        shape = (ctypes.c_int64 * 4)()
        _check(self._lib.ivr_scene_image_shape(scene_handle, shape))
        rays = ctypes.c_size_t()
        _check(self._lib.ivr_scene_ray_count(scene_handle, ctypes.byref(rays)))
        return (rays.value, shape[3]) if rays.value else tuple(shape)

    def step(self, scene, volume=None, base_dir=None):
        """(step, estimated_error): the integrator step (voxels) a render of the scene uses — its
        own, or the one chosen for its integrator's "tolerance" (estimated_error 0 without)."""
        s = self._scene(scene, volume, base_dir)
        try:
            step, error = ctypes.c_double(), ctypes.c_double()
            _check(self._lib.ivr_scene_step(self._live(), s, _PRECISIONS[self.precision],
                                            ctypes.byref(step), ctypes.byref(error)))
            return step.value, error.value
        finally:
            self._lib.ivr_scene_release(s)

    def render(self, scene, volume=None, step=0.0, base_dir=None, _split=None):
        """The image of every view: float32 (views, H, W, C)."""
        s = self._scene(scene, volume, base_dir, _slab_of(_split))
        failure = []
        try:
            shape = self._image_shape(s)
            out = np.empty(shape, dtype=np.float32)
            image = out.ctypes.data_as(ctypes.POINTER(ctypes.c_float))
            if _split is None:
                _check(self._lib.ivr_render(self._live(), s, _PRECISIONS[self.precision], step,
                                            image, out.size))
            else:  # (split, rank, ranks, add, nz, weights): ivr.mpi's workers over slabs (1) or
                # segments (2), their slabs in proportion to the weights (None: equal)
                split, rank, ranks, add, _, weights = _split
                status = self._lib.ivr_render_split_weighted(
                    self._live(), s, _PRECISIONS[self.precision], step, split, rank, ranks,
                    _doubles(weights), _sum_fn(add, failure), None, image, out.size)
                if failure:
                    raise failure[0]
                _check(status)
            return out
        finally:
            self._lib.ivr_scene_release(s)

    def gradient(self, scene, volume, target, wrt=("density",), mode="auto", loss="mse", step=0.0,
             base_dir=None, info=None, deterministic=False, _split=None, _shared=None):
        """(loss, {group: array}) of the loss of the render against `target` (its shape).
        `wrt` names groups as `ivr gradient --wrt` (density, tf, tf_points, scales, background,
        camera, step, "voxels:3,17,40-45", rays: a ray list's (R, 8) origins, directions and
        ends); `info`, a dict, receives the mode that ran. `deterministic`: the density gradient
        summed in fixed point (adjoint mode, where the device has 64-bit integer atomics), the
        same bits on every run (and under ivr.mpi.gradient, over views or slabs, one process's
        bits)."""
        groups = wrt if isinstance(wrt, str) else ",".join(wrt)
        s = self._scene(scene, volume, base_dir, _slab_of(_split))
        try:
            shape = self._image_shape(s)
            t = np.ascontiguousarray(target, dtype=np.float32)
            if t.shape != shape and t.size == int(np.prod(shape)) and t.squeeze().shape == \
                    tuple(d for d in shape if d != 1):
                t = t.reshape(shape)
            if t.shape != shape:
                raise Error("IVR_ERROR_INVALID_ARGUMENT",
                            f"target has shape {t.shape} but the scene renders {shape}")
            r = _capi.HANDLE()
            args = (self._live(), s, t.ctypes.data_as(_FLOAT_P), t.size, groups.encode())
            failure = []
            if _split is not None:  # (split, rank, ranks, add, nz, weights): ivr.mpi's workers
                split, rank, ranks, add, _, weights = _split  # over slabs
                status = self._lib.ivr_gradient_split_deterministic(
                    *args, _choice(_LOSSES, loss, "loss"), _PRECISIONS[self.precision], step,
                    split, 1 if deterministic else 0, rank, ranks, _doubles(weights),
                    _sum_fn(add, failure), None, ctypes.byref(r))
            else:
                how = (_choice(_MODES, mode, "mode"), _choice(_LOSSES, loss, "loss"),
                       _PRECISIONS[self.precision], step)
                if deterministic or _shared is not None:
                    # (rank, ranks, add, weights): ivr.mpi's workers over views, every one the
                    # whole gradient, their shares in proportion to the weights (None: equal)
                    rank, ranks, add, weights = (_shared if _shared is not None
                                                 else (0, 1, None, None))
                    status = self._lib.ivr_gradient_shared_weighted(
                        *args, *how, 1 if deterministic else 0, rank, ranks, _doubles(weights),
                        _capi.SUM_FN() if add is None else _sum_fn(add, failure), None,
                        ctypes.byref(r))
                else:
                    status = self._lib.ivr_gradient(*args, *how, ctypes.byref(r))
            if failure:
                raise failure[0]
            _check(status)
        finally:
            self._lib.ivr_scene_release(s)
        try:
            value, arrays, ran = self._result(r)
        finally:
            self._lib.ivr_result_release(r)
        if info is not None:
            info["mode"] = ran
        return value, arrays

    def jacobian(self, scene, volume=None, wrt=("tf",), step=0.0, base_dir=None):
        """d pixel / d parameter: float64 (views, H, W, C, P), P in `wrt` order."""
        groups = wrt if isinstance(wrt, str) else ",".join(wrt)
        s = self._scene(scene, volume, base_dir)
        try:
            r = _capi.HANDLE()
            _check(self._lib.ivr_jacobian(self._live(), s, groups.encode(),
                                          _PRECISIONS[self.precision], step, ctypes.byref(r)))
        finally:
            self._lib.ivr_scene_release(s)
        try:
            return self._result(r)[1]["jacobian"]
        finally:
            self._lib.ivr_result_release(r)

    # --- absorption tomography: log(I / I_in) = -N v (the scene's model and TF are not used) --

    def _ray_shape(self, scene_handle):
        return self._image_shape(scene_handle)[:-1] + (1,)

    def _rays(self, scene_handle, values, what):
        """`values` as contiguous float32 of the scene's ray shape ((views, H, W, 1), a ray
        list's (rays, 1)); (views, H, W) or (rays,) also accepted."""
        shape = self._ray_shape(scene_handle)
        a = np.ascontiguousarray(values, dtype=np.float32)
        if a.shape == shape[:-1]:
            a = a.reshape(shape)
        if a.shape != shape:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"{what} have shape {a.shape} but the scene's rays give {shape} "
                        f"(or {shape[:-1]})")
        return a

    def _grid_scene(self, scene, grid, base_dir):
        """A scene handle whose volume is the grid: the scene's own, or zeros of shape `grid`."""
        volume = None if grid is None else np.zeros(tuple(grid), dtype=np.float32)
        return self._scene(scene, volume, base_dir)

    def _volume_out(self, scene_handle):
        shape = (ctypes.c_int64 * 3)()
        _check(self._lib.ivr_scene_volume_shape(scene_handle, shape))
        return np.empty(tuple(shape), dtype=np.float32)

    def project(self, scene, volume=None, base_dir=None):
        """Line integrals N v of the scene's volume (or `volume`, (Z, Y, X)) along every camera
        ray, evaluated exactly: float32 (views, H, W, 1) — a ray list's (rays, 1)."""
        s = self._scene(scene, volume, base_dir)
        try:
            out = np.empty(self._ray_shape(s), dtype=np.float32)
            _check(self._lib.ivr_project(self._live(), s, _PRECISIONS[self.precision], None, 0,
                                         out.ctypes.data_as(_FLOAT_P), out.size))
            return out
        finally:
            self._lib.ivr_scene_release(s)

    def backproject(self, scene, lines, grid=None, base_dir=None):
        """N^T p, the exact transpose of project: `lines` (views, H, W[, 1]) — a ray list's
        (rays[, 1]) — onto the scene's
        grid (or a grid of shape `grid` = (Z, Y, X)): float32 (Z, Y, X)."""
        s = self._grid_scene(scene, grid, base_dir)
        try:
            p = self._rays(s, lines, "lines")
            out = self._volume_out(s)
            _check(self._lib.ivr_backproject(self._live(), s, _PRECISIONS[self.precision],
                                             p.ctypes.data_as(_FLOAT_P), p.size,
                                             out.ctypes.data_as(_FLOAT_P), out.size))
            return out
        finally:
            self._lib.ivr_scene_release(s)

    def tomo(self, scene, lines, solver=None, iterations=None, nonneg=None, tv=None, tikhonov=None,
             tolerance=None, tv_epsilon=None, tv_reweight=None, relaxation=None, progress=None,
             grid=None, base_dir=None, info=None, _split=None):
        """(volume, history): the scene's grid (or `grid`) reconstructed from line integrals
        `lines` (views, H, W[, 1]) by least squares (cgls, sirt or lsqr), optionally with x >= 0,
        Tikhonov or smoothed-TV regularisation; volume float32 (Z, Y, X), history a list of
        {"iteration", "residual" (|p - N x| / |p|), "seconds"}. progress(entry) is called after
        every iteration with that entry; returning False stops (the last iterate is returned).
        `info`, a dict, receives stop_reason, setup_seconds and seconds. Options left at None take
        the library's defaults (ivr_tomo_options_init: cgls, 50 iterations, no regulariser)."""
        from . import _tomo
        return _tomo.tomo(self, scene, lines, solver, iterations, nonneg, tv, tikhonov, tolerance,
                          tv_epsilon, tv_reweight, relaxation, progress, grid, base_dir, info,
                          _split)

    def lines_from_intensities(self, scene, intensities, clamp=0.0, base_dir=None):
        """Line integrals p = -log(I / I_in) / a from intensities (views, H, W[, 1]), with I_in
        the scene's background and a its identity TF's extinction_scale: float32
        (views, H, W, 1). I <= 0 raises unless clamp in (0, 1) raises I to clamp * I_in."""
        s = self._scene(scene, None, base_dir)
        try:
            i = self._rays(s, intensities, "intensities")
            out = np.empty(i.shape, dtype=np.float32)
            _check(self._lib.ivr_lines_from_intensities(s, i.ctypes.data_as(_FLOAT_P), i.size,
                                                        float(clamp),
                                                        out.ctypes.data_as(_FLOAT_P), out.size))
            return out
        finally:
            self._lib.ivr_scene_release(s)

    # --- inverse rendering (bindings/python/ivr/_reconstruct.py) ------------------------------

    def reconstruct(self, scene, targets, volume=None, wrt=("density",), iterations=None, lr=None,
                    optimizer=None, schedule=None, loss=None, tv=None, smoothness=None,
                    tf_smoothness=None, batch=None, levels=None, init=None, init_value=None,
                    seed=None, step=None, progress=None, checkpoint=None, resume=False,
                    checkpoint_every=0, step_every=None, step_gamma=None, min_lr=None,
                    tv_epsilon=None, mode=None, base_dir=None, _workers=None):
        """Recovers the densities (wrt "density"), the TF's parameters ("tf") or both from
        `targets`, the images (views, H, W, C) of the scene's cameras. The scene's volume (or
        `volume`, (Z, Y, X)) gives the grid and, with init="scene", the start ("zeros",
        "constant": init_value everywhere; emission-absorption needs "constant" or "scene"); its
        TF is the known or starting TF. Coarse to fine over `levels` (0: automatic), `batch`
        random views per iteration (0: all), priors tv / smoothness / tf_smoothness; optimizer
        "auto" (adam; lbfgs for the TF alone), "adam", "sgd" (needs lr) or "lbfgs" (TF only);
        lr 0: automatic; schedule "constant", "step" (lr * step_gamma^(k // step_every)) or
        "cosine" (down to min_lr). progress(entry) is called after every iteration with its
        history entry; returning False stops. checkpoint: a path prefix, written at the end
        (and every checkpoint_every iterations); resume=True continues from it first.
        Returns a dict: "volume" (float32 (Z, Y, X), with density), "tf" (float64 rows x
        columns in the TF-gradient layout, e.g. [r, g, b, extinction] per control point, with
        tf), "history" (a list of {"iteration", "level", "loss", "prior", "lr", "seconds",
        "views"}), "iterations" (completed), "stopped" (by progress), and the "optimizer",
        "lr" and "levels" that ran. Options left at None take the library's defaults
        (ivr_reconstruct_options_init: 300 iterations, optimizer auto, lr automatic, ...)."""
        from . import _reconstruct
        return _reconstruct.reconstruct(
            self, scene, targets, volume, wrt, iterations, lr, optimizer, schedule, loss, tv,
            smoothness, tf_smoothness, batch, levels, init, init_value, seed, step, progress,
            checkpoint, resume, checkpoint_every, step_every, step_gamma, min_lr, tv_epsilon,
            mode, base_dir, _workers)

    def viewpoint(self, scene, volume=None, view=None, iterations=None, lr=None, optimizer=None,
                  step=None, progress=None, base_dir=None):
        """The camera on camera `view`'s orbit (about its target and up axis, distance kept)
        whose image has the highest entropy (ivr.image_entropy), by gradient ascent in
        azimuth and elevation (optimizer "adam", "sgd" or "lbfgs"; lr in radians, 0: 0.05).
        Returns {"camera": {"eye", "target", "up", "fov_y", "width", "height"} (a scene's
        camera object), "entropy_start", "entropy_best", "history": [{"iteration", "entropy",
        "azimuth", "elevation"} (degrees), the start first]}. progress(entry) returning False
        stops. Options left at None take the library's defaults (ivr_viewpoint_options_init)."""
        from . import _reconstruct
        return _reconstruct.viewpoint(self, scene, volume, view, iterations, lr, optimizer, step,
                                      progress, base_dir)

    def _result(self, r):
        loss, mode = ctypes.c_double(), ctypes.c_int()
        _check(self._lib.ivr_result_info(r, ctypes.byref(loss), ctypes.byref(mode), None))
        count = ctypes.c_size_t()
        _check(self._lib.ivr_result_array_count(r, ctypes.byref(count)))
        arrays = {}
        for i in range(count.value):
            name, rank, shape = ctypes.c_char_p(), ctypes.c_int(), (ctypes.c_int64 * 5)()
            _check(self._lib.ivr_result_array_shape(r, i, ctypes.byref(name), ctypes.byref(rank),
                                                    shape))
            dims = tuple(shape[:rank.value])
            values = np.empty(dims, dtype=np.float64)
            _check(self._lib.ivr_result_array_data(
                r, i, values.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), values.size))
            arrays[name.value.decode()] = values
        return loss.value, arrays, _MODE_NAMES.get(mode.value, "?")


# Device-resident sessions (bindings/python/ivr/_session.py): imported last, as they build on the
# names above.
from ._session import DensityOptimizer, DeviceArray, Session  # noqa: E402
# The split of views among workers (bindings/python/ivr/_shares.py).
from ._shares import _doubles, view_shares_by  # noqa: E402,F401
# The one-shot functions, each opening a Context for the call (bindings/python/ivr/_oneshot.py).
from ._oneshot import (backproject, lines_from_intensities, project, reconstruct,  # noqa: E402
                       tomo, viewpoint)


def _require_a_platform():
    """`import ivr` fails at once, naming what is missing, where the library cannot be loaded or
    no OpenCL platform exists — rather than at the first render, deep in a training script."""
    try:
        _library()
    except OSError as e:
        raise ImportError(f"ivr: {e}") from None
    try:
        devices()
    except Error as e:
        raise ImportError(f"ivr: {e.message}; GPUs need their vendor's OpenCL driver, CPUs PoCL "
                          f"(Debian: apt-get install pocl-opencl-icd)") from None


_require_a_platform()

