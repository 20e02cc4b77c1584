"""_session.py — device-resident sessions for ivr: Session, DeviceArray and DensityOptimizer over
the C API's ivr_session, ivr_array and ivr_density_optimizer handles."""
import ctypes
import json

import numpy as np

from . import (Context, Error, _Owned, _capi, _check, _choice, _library, _optional_choice,
               _volume_array, ray_array, _DTYPES, _FLOAT_P, _LOSSES, _MODE_NAMES, _MODES,
               _PRECISIONS)

_ARRAY_DTYPES = {np.dtype(np.float32): 0, np.dtype(np.float64): 1}  # ivr_dtype of device arrays
_ARRAY_NUMPY = {0: np.dtype(np.float32), 1: np.dtype(np.float64)}
_EMPTY_SPACE = {"auto": 0, "on": 1, "off": 2}
_OPTIMIZERS = {"adam": 1, "sgd": 2}


def _context_handle(owner):
    """The C context of a Context or a Session."""
    if isinstance(owner, Context):
        return owner._live()
    if isinstance(owner, Session):
        owner._live()
        return owner._ctx
    raise Error("IVR_ERROR_INVALID_ARGUMENT",
                f"device arrays are made on an ivr.Context or ivr.Session, got "
                f"{type(owner).__name__}")


def _host_floats(values, what):
    """`values` as contiguous float32 or float64 host memory (lists and scalars become float64;
    arrays of other dtypes are refused rather than silently converted)."""
    if isinstance(values, np.ndarray):
        if values.dtype not in _ARRAY_DTYPES:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"{what} must be float32 or float64, got {values.dtype}")
        return np.ascontiguousarray(values)
    return np.ascontiguousarray(values, dtype=np.float64)


class _Mapping:
    """One ivr_array_map of a DeviceArray as numpy's array interface; unmaps when numpy lets go."""

    def __init__(self, array):
        self._array = array
        ptr = ctypes.c_void_p()
        _check(array._lib.ivr_array_map(array._live(), ctypes.byref(ptr)))
        self._mapped = True
        self.__array_interface__ = {"shape": array.shape, "typestr": array.dtype.str,
                                    "data": (ptr.value, False), "version": 3}

    def __del__(self):
        if getattr(self, "_mapped", False) and getattr(self._array, "_handle", None):
            self._array._lib.ivr_array_unmap(self._array._handle)
            self._mapped = False


class DeviceArray(_Owned):
    """An array in device memory (ivr_array): shape, dtype (float32 or float64) and a buffer
    that keeps its context alive. Operation results stay valid (their values unchanged) while
    the DeviceArray lives; np.asarray(a) or a.numpy() downloads it.

        a = ivr.DeviceArray(ctx, (16, 16, 16))               # zeros, float32
        b = ivr.DeviceArray.from_numpy(ctx, volume)          # a copy of a host array

    close() releases it at once; views of the same buffer (Session.volume) and results held
    elsewhere are not affected.
    """
    _release, _what = "ivr_array_release", "device array"
    borrowed = False  # wrap(): the device uses the host memory itself

    def __init__(self, context, shape, dtype="float32"):
        self._lib = _library()
        self._handle = None
        dt = np.dtype(dtype)
        if dt not in _ARRAY_DTYPES:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"device arrays hold float32 or float64, got {dt}")
        dims = (int(shape),) if np.isscalar(shape) else tuple(int(d) for d in shape)
        c_shape = (ctypes.c_int64 * max(len(dims), 1))(*dims)
        handle = _capi.HANDLE()
        _check(self._lib.ivr_array_create(_context_handle(context), len(dims), c_shape,
                                          _ARRAY_DTYPES[dt], ctypes.byref(handle)))
        self._adopt(handle)

    @classmethod
    def from_numpy(cls, context, array):
        """A new device array with `array`'s shape and values (float32 or float64; lists and
        scalars become float64)."""
        a = _host_floats(array, "from_numpy: the array")
        out = cls(context, a.shape or (1,), a.dtype)
        out.upload(a)
        return out

    @classmethod
    def wrap(cls, context, array):
        """A device array over `array`'s own memory (a C-contiguous float32 or float64 numpy
        array, kept alive by the DeviceArray): no copy where the device's memory is the host's
        (`borrowed` is then True: CPUs through PoCL), one copy in elsewhere. Leave `array` alone
        while an operation that reads the DeviceArray runs."""
        a = np.asarray(array)
        if a.dtype not in _ARRAY_DTYPES or not a.flags.c_contiguous or not a.flags.writeable:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"wrap: a writable C-contiguous float32 or float64 array, got {a.dtype}"
                        f"{'' if a.flags.c_contiguous else ', not contiguous'}"
                        f"{'' if a.flags.writeable else ', read-only'}")
        lib = _library()
        dims = a.shape or (1,)
        handle, borrowed = _capi.HANDLE(), ctypes.c_int()
        _check(lib.ivr_array_wrap(_context_handle(context), a.ctypes.data_as(ctypes.c_void_p),
                                  len(dims), (ctypes.c_int64 * len(dims))(*dims),
                                  _ARRAY_DTYPES[a.dtype], ctypes.byref(borrowed),
                                  ctypes.byref(handle)))
        out = cls._wrap(handle)
        out._host = a  # the memory the device uses stays alive with the array
        out.borrowed = bool(borrowed.value)
        return out

    def view(self):
        """The values as a numpy array over the mapped device memory: no copy where the
        device's memory is the host's, one elsewhere. It keeps this DeviceArray alive, and is
        unmapped when the last numpy (or torch.from_numpy) user of it goes."""
        return np.asarray(_Mapping(self))

    @classmethod
    def _wrap(cls, handle):
        """Takes over a reference the C API handed out."""
        out = cls.__new__(cls)
        out._lib = _library()
        out._handle = None
        out._adopt(handle)
        return out

    def _adopt(self, handle):
        self._handle = handle
        try:
            rank, shape, dtype = ctypes.c_int(), (ctypes.c_int64 * 8)(), ctypes.c_int()
            _check(self._lib.ivr_array_info(handle, ctypes.byref(rank), shape,
                                            ctypes.byref(dtype)))
        except BaseException:
            self.close()
            raise
        self._shape = tuple(shape[:rank.value])
        self._dtype = _ARRAY_NUMPY[dtype.value]

    @property
    def shape(self):
        return self._shape

    @property
    def dtype(self):
        return self._dtype

    @property
    def ndim(self):
        return len(self._shape)

    @property
    def size(self):
        return int(np.prod(self._shape, dtype=np.int64))

    def __len__(self):
        return self._shape[0]

    def numpy(self):
        """Downloads the array (waiting for what writes it): a new numpy array of its shape and
        dtype."""
        out = np.empty(self._shape, dtype=self._dtype)
        _check(self._lib.ivr_array_download(self._live(), out.ctypes.data_as(ctypes.c_void_p),
                                            _ARRAY_DTYPES[self._dtype], out.size))
        return out

    def __array__(self, dtype=None, copy=None):
        if copy is False:
            raise ValueError("a DeviceArray is always copied to host memory")
        out = self.numpy()
        return out if dtype is None else out.astype(dtype, copy=False)

    def upload(self, values):
        """Host -> device: `values` (float32 or float64, any shape with the same element count),
        converted to the array's dtype. The host memory may be reused once this returns."""
        a = _host_floats(values, "upload: the values")
        if a.size != self.size:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"upload: {a.size} values (shape {a.shape}) for an array of shape "
                        f"{self._shape} ({self.size} elements)")
        _check(self._lib.ivr_array_upload(self._live(), a.ctypes.data_as(ctypes.c_void_p),
                                          _ARRAY_DTYPES[a.dtype], a.size))
        return self

    def wait(self):
        """Waits until the commands that write the array have finished."""
        _check(self._lib.ivr_array_wait(self._live()))
        return self

    def item(self):
        """The value of a one-element array (e.g. a loss) as a Python float."""
        if self.size != 1:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"item(): the array has shape {self._shape}, not one element")
        return float(self.numpy().reshape(-1)[0])

    def __float__(self):
        return self.item()

    def __repr__(self):
        state = "" if getattr(self, "_handle", None) else ", closed"
        return f"ivr.DeviceArray(shape={self._shape}, dtype={self._dtype.name}{state})"


class Session(_Owned):
    """One scene resident on a context's device (ivr_session): densities, transfer function,
    cameras, target and the empty-space grid stay there between calls; each setter uploads only
    its part, and operations return DeviceArrays that are read back only when asked.

        with ivr.Session(ctx, scene, volume) as s:
            s.set_target(images)
            opt = ivr.DensityOptimizer(s, "adam", lr=0.02)
            for _ in range(100):
                loss, g = s.gradient(wrt=("density",))
                s.step(opt, g["density"])
            print(float(loss), s.volume.numpy().mean())

    `scene` is a dict with docs/design.md's fields (or JSON text), as Context.render takes it;
    `volume` ((Z, Y, X) float32/float64/uint8/uint16) replaces the scene's own, which may then
    be left out. `precision` ("f32"/"f64") defaults to the context's; `step` > 0 overrides the
    integrator's step; `empty_space` is "auto", "on" or "off"; `brick_size` 0 chooses itself.
    Wherever a DeviceArray is expected a numpy array may be given instead: it is uploaded for
    that call (float32; float64 kept in float64). A setter or operation that fails raises
    ivr.Error and leaves the session as it was. Calls from several threads are serialised;
    sessions of one context may run on different threads at once."""
    _release, _what = "ivr_session_release", "session"

    def __init__(self, context, scene, volume=None, precision=None, step=None, empty_space=None,
                 min_empty_fraction=None, brick_size=None, base_dir=None):
        self._lib = _library()
        self._handle = self._ctx = None
        self.precision = context.precision if precision is None else precision
        options = _capi.filled(
            _capi.SessionOptions, self._lib.ivr_session_options_init, _check,
            precision=_choice(_PRECISIONS, self.precision, "precision"), step=step,
            empty_space=_optional_choice(_EMPTY_SPACE, empty_space, "empty_space"),
            min_empty_fraction=min_empty_fraction, brick_size=brick_size)
        on_device = isinstance(volume, DeviceArray)
        if volume is not None and not on_device:
            _volume_array(volume)
        s = context._scene(scene, None if on_device else volume, base_dir)
        try:
            rays = ctypes.c_size_t()
            _check(self._lib.ivr_scene_ray_count(s, ctypes.byref(rays)))
            self._ray_list = rays.value > 0
            handle = _capi.HANDLE()
            _check(self._lib.ivr_session_create(context._live(), s, ctypes.byref(options),
                                                ctypes.byref(handle)))
        finally:
            self._lib.ivr_scene_release(s)
        self._handle = handle
        self._ctx = context._live()
        _check(self._lib.ivr_context_retain(self._ctx))  # for set_tf and uploads
        if on_device:
            self.set_volume(volume)

    def close(self):
        """Releases the session now (also done when it is garbage-collected); arrays it returned
        stay valid."""
        super().close()
        if getattr(self, "_ctx", None):
            self._lib.ivr_context_release(self._ctx)
            self._ctx = None

    def __repr__(self):
        if not getattr(self, "_handle", None):
            return "ivr.Session(closed)"
        return (f"ivr.Session(image_shape={self.image_shape}, volume_shape={self.volume_shape}, "
                f"precision={self.precision!r})")

    # --- device arrays of the session's context ------------------------------------------------

    def _array(self, value, what, shape=None, dtype=None, of="the session renders"):
        """(DeviceArray, handle): `value` itself, or a numpy array uploaded for this call (with
        `shape` when given, `of` naming it; `dtype` when given, else float32 unless it is
        float64)."""
        if isinstance(value, DeviceArray):
            return value, value._live()
        a = _host_floats(value, what) if dtype is None else \
            np.ascontiguousarray(_host_floats(value, what), dtype=dtype)
        if shape is not None:
            a = self._fit(a, shape, what, of)
        out = DeviceArray(self, a.shape or (1,), a.dtype)
        out.upload(a)
        return out, out._handle

    @staticmethod
    def _fit(a, shape, what, of="the session renders"):
        """`a` reshaped to `shape` when only axes of length 1 differ (as Context.grad)."""
        shape = tuple(shape)
        if a.shape != shape and a.size == int(np.prod(shape)) and \
                a.squeeze().shape == tuple(d for d in shape if d != 1):
            a = a.reshape(shape)
        if a.shape != shape:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"{what} has shape {a.shape} but {of} {shape}")
        return a

    def _real(self):
        return np.float64 if self.precision == "f64" else np.float32

    # --- setters ---------------------------------------------------------------------------------

    def set_volume(self, volume):
        """New densities: a (Z, Y, X) numpy array (float32/float64 as they are, uint8/uint16
        mapped to [0, 1]) or a DeviceArray of that shape, checked on the device (finite, >= 0;
        the message names the first bad voxel). Its shape may differ from the old one."""
        h = self._live()
        if isinstance(volume, DeviceArray):
            _check(self._lib.ivr_session_set_volume_array(h, volume._live()))
            return
        v = _volume_array(volume)
        shape = (ctypes.c_int64 * 3)(*v.shape)
        _check(self._lib.ivr_session_set_volume(h, v.ctypes.data_as(ctypes.c_void_p),
                                                _DTYPES[v.dtype], shape))

    def set_tf(self, tf):
        """A new transfer function: docs/design.md's "tf" object (a dict or JSON text)."""
        h = self._live()
        text = tf if isinstance(tf, str) else json.dumps(tf)
        t = _capi.HANDLE()
        _check(self._lib.ivr_tf_from_json(self._ctx, text.encode(), ctypes.byref(t)))
        try:
            _check(self._lib.ivr_session_set_tf(h, t))
        finally:
            self._lib.ivr_tf_release(t)

    def set_cameras(self, cameras):
        """New cameras: a scene's "cameras" list (cameras and orbits; one dict is a list of
        one). Their number and image size may change; a target of the old shape is dropped."""
        h = self._live()
        if isinstance(cameras, dict):
            cameras = [cameras]
        text = cameras if isinstance(cameras, str) else json.dumps(list(cameras))
        _check(self._lib.ivr_session_set_cameras_json(h, text.encode()))
        self._ray_list = False

    def set_rays(self, rays):
        """A ray list instead of the cameras (docs/design.md, "Ray lists"): an (R, 8) array of
        ox oy oz dx dy dz t_start t_end (t_start may be -inf, t_end inf: from the box entry, to
        its exit) or (R, 6) start and end points. Images and targets are then (R, C); a bad ray
        raises ivr.Error naming it and its field, and the session keeps its geometry."""
        h = self._live()
        a = ray_array(rays)
        _check(self._lib.ivr_session_set_rays(
            h, a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), a.shape[0], a.shape[1]))
        self._ray_list = True

    def set_integrator(self, integrator):
        """A new integrator: a scene's "integrator" object ({"scheme", "step",
        "min_transmittance", "tolerance"}; a dict or JSON text)."""
        h = self._live()
        text = integrator if isinstance(integrator, str) else json.dumps(integrator)
        _check(self._lib.ivr_session_set_integrator_json(h, text.encode()))

    def set_background(self, background):
        """A new background: [r, g, b] (emission-absorption) or one value (grey; absorption:
        I_in)."""
        h = self._live()
        b = np.asarray(background, dtype=np.float64).reshape(-1)
        if b.size == 1:
            b = np.repeat(b, 3)
        if b.size != 3:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"background must be one value or [r, g, b], got {b.size} values")
        _check(self._lib.ivr_session_set_background(h, (ctypes.c_double * 3)(*b)))

    def set_target(self, target):
        """The loss target of gradient(): the image shape (views, H, W, C) — also (H, W, C) for
        one view, (views, H, W) or (H, W) for C = 1 — as a numpy array or a DeviceArray;
        finite."""
        h = self._live()
        if isinstance(target, DeviceArray):
            _check(self._lib.ivr_session_set_target_array(h, target._live()))
            return
        t = self._fit(np.ascontiguousarray(target, dtype=np.float32), self.image_shape, "target")
        _check(self._lib.ivr_session_set_target(h, t.ctypes.data_as(_FLOAT_P), t.size))

    # --- what it holds ---------------------------------------------------------------------------

    @property
    def image_shape(self):
        """(views, H, W, C) of render(); (rays, C) for a ray list."""
        shape = (ctypes.c_int64 * 4)()
        _check(self._lib.ivr_session_image_shape(self._live(), shape))
        return (shape[2], shape[3]) if self._ray_list else tuple(shape)

    @property
    def volume_shape(self):
        """(Z, Y, X) of the densities."""
        shape = (ctypes.c_int64 * 3)()
        _check(self._lib.ivr_session_volume_shape(self._live(), shape))
        return tuple(shape)

    @property
    def volume(self):
        """The densities as a DeviceArray view of the session's own buffer (its precision):
        optimiser steps show through it; a later set_volume gives the session a new buffer."""
        out = _capi.HANDLE()
        _check(self._lib.ivr_session_volume(self._live(), ctypes.byref(out)))
        return DeviceArray._wrap(out)

    # --- operations: enqueued on the device; the results are DeviceArrays -----------------------

    def _one(self, function, *args):
        out = _capi.HANDLE()
        _check(function(self._live(), *args, ctypes.byref(out)))
        return DeviceArray._wrap(out)

    def render(self):
        """Every view: (views, H, W, C), float32 (float64 in a session of precision f64)."""
        return self._one(self._lib.ivr_session_render)

    def gradient(self, target=None, wrt=("density",), mode="auto", loss="mse",
                 deterministic=False, info=None):
        """(loss, {group: DeviceArray}): the loss (shape (1,); float(loss) reads it) of the
        render against `target` (None: set_target's; else, for this call only, a DeviceArray of
        the image shape or a numpy array as set_target takes it) and its gradient for every
        group of `wrt` (as ivr gradient --wrt: density, tf, tf_points, scales, background, camera,
        step, "voxels:3,17,40-45", rays), keyed by group name ("voxels" for voxels:LIST) in `wrt`
        order.
        mode "auto", "forward" or "adjoint"; loss "mse", "l1" or "dot" (sum(target * image):
        the gradient is the vector-Jacobian product with `target` as dL/dimage); deterministic sums the
        adjoint's density gradient in fixed point. `info`, a dict, receives the mode that ran."""
        h = self._live()
        text = wrt if isinstance(wrt, str) else ",".join(wrt)
        if target is not None and not isinstance(target, DeviceArray):
            target = self._fit(np.ascontiguousarray(target, dtype=np.float32), self.image_shape,
                               "target")
        t, t_handle = (None, None) if target is None else self._array(target, "target")
        value = _capi.HANDLE()
        groups = (_capi.HANDLE * (text.count(",") + 1))()  # at least as many as the library's
        count, ran = ctypes.c_size_t(), ctypes.c_int()
        _check(self._lib.ivr_session_gradient(
            h, t_handle, text.encode(), _choice(_MODES, mode, "mode"),
            _choice(_LOSSES, loss, "loss"), int(bool(deterministic)), ctypes.byref(value),
            groups, len(groups), ctypes.byref(count), ctypes.byref(ran)))
        del t
        loss_array = DeviceArray._wrap(value)
        arrays = {}
        for i in range(count.value):
            name = ctypes.c_char_p()
            _check(self._lib.ivr_array_name(groups[i], ctypes.byref(name)))
            arrays[name.value.decode()] = DeviceArray._wrap(groups[i])
        if info is not None:
            info["mode"] = _MODE_NAMES.get(ran.value, "?")
        return loss_array, arrays

    def jacobian(self, wrt=("tf",)):
        """d pixel / d parameter (forward mode): (views, H, W, C, P), P in `wrt` order;
        float32 (float64 in a session of precision f64)."""
        text = wrt if isinstance(wrt, str) else ",".join(wrt)
        return self._one(self._lib.ivr_session_jacobian, text.encode())

    def project(self, volume=None):
        """Line integrals N v of the densities (or of `volume`, (Z, Y, X)) along every pixel ray,
        evaluated exactly: (views, H, W, 1) in the session's precision."""
        v, handle = (None, None) if volume is None else self._array(volume, "volume")
        out = self._one(self._lib.ivr_session_project, handle)
        del v
        return out

    def backproject(self, lines):
        """N^T p, the exact transpose of project: `lines` (views, H, W, 1) — a numpy array may
        also be (views, H, W) — onto the grid, (Z, Y, X)."""
        shape = self.image_shape[:-1] + (1,)
        p, handle = self._array(lines, "lines", None if isinstance(lines, DeviceArray) else shape,
                                of="the session's rays are")
        out = self._one(self._lib.ivr_session_backproject, handle)
        del p
        return out

    def loss(self, image, target, kind="mse"):
        """The loss (mean over every element, "mse" or "l1"; shape (1,)) of `image` against
        `target` (the same element count)."""
        a, ha = self._array(image, "image")
        b, hb = self._array(target, "target")
        out = self._one(self._lib.ivr_session_loss, ha, hb, _choice(_LOSSES, kind, "kind"))
        del a, b
        return out

    def step(self, optimizer, gradient):
        """One optimiser step on the densities in place with their gradient (the density
        group of gradient(); a numpy array is uploaded in the session's precision); the
        densities stay >= 0."""
        h = self._live()
        if not isinstance(optimizer, DensityOptimizer):
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"step: optimizer must be an ivr.DensityOptimizer, got "
                        f"{type(optimizer).__name__}")
        g, handle = self._array(gradient, "gradient", self.volume_shape, self._real(),
                                of="the densities are")
        _check(self._lib.ivr_session_step(h, optimizer._live(), handle))
        del g

    def last_stats(self):
        """What the last operation did, once it has finished (this waits): kernel_seconds,
        build_seconds, samples, device_bytes, step (voxels), skipped_empty, empty_fraction."""
        st = _capi.OperationStats()
        _check(self._lib.ivr_session_last_stats(self._live(), ctypes.byref(st)))
        return {"kernel_seconds": st.kernel_seconds, "build_seconds": st.build_seconds,
                "samples": int(st.samples), "device_bytes": int(st.device_bytes),
                "step": st.step, "skipped_empty": bool(st.skipped_empty),
                "empty_fraction": st.empty_fraction}

    def finish(self):
        """Waits for every command enqueued so far."""
        _check(self._lib.ivr_session_finish(self._live()))


class DensityOptimizer(_Owned):
    """Adam or SGD (with momentum) state for a session's densities (ivr_density_optimizer),
    sized and typed for the session as it is now; Session.step applies it (densities >= 0)."""
    _release, _what = "ivr_density_optimizer_release", "density optimizer"

    def __init__(self, session, kind="adam", lr=0.01):
        self._lib = _library()
        self._handle = None
        self.kind, self.lr = kind, float(lr)
        handle = _capi.HANDLE()
        _check(self._lib.ivr_density_optimizer_create(
            session._live(), _choice(_OPTIMIZERS, kind, "kind"), self.lr, ctypes.byref(handle)))
        self._handle = handle

    def __repr__(self):
        return f"ivr.DensityOptimizer(kind={self.kind!r}, lr={self.lr})"
