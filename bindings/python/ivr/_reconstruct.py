"""_reconstruct.py — reconstruction and viewpoint selection for ivr.Context (over the C API's
ivr_reconstruction handle and ivr_select_viewpoint); kept apart from __init__.py for its size."""
import ctypes
import os

import numpy as np

from . import (Error, _capi, _check, _choice, _doubles, _optional_choice, _slab_of, _sum_fn,
               _FLOAT_P,
               _LOSSES, _MODES, _PRECISIONS)

_OPTIMIZERS = {"auto": 0, "adam": 1, "sgd": 2, "lbfgs": 3}
_OPTIMIZER_NAMES = {v: k for k, v in _OPTIMIZERS.items()}
_SCHEDULES = {"constant": 0, "step": 1, "cosine": 2}
_INITS = {"scene": 0, "zeros": 1, "constant": 2}
_GROUPS = ("density", "tf")


def _groups(wrt):
    names = [w.strip() for w in (wrt.split(",") if isinstance(wrt, str) else wrt)]
    unknown = [n for n in names if n not in _GROUPS]
    if unknown:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"reconstruct: wrt names what is optimised, 'density' and/or 'tf'; got "
                    f"{unknown[0]!r}")
    if not names:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    "reconstruct: wrt is empty (nothing to optimise): give 'density' and/or 'tf'")
    return "density" in names, "tf" in names


def _entry(it):
    return {"iteration": it.iteration, "level": it.level, "loss": it.loss, "prior": it.prior,
            "lr": it.lr, "seconds": it.seconds, "views": it.views}


def _targets(ctx, scene_handle, targets):
    shape = ctx._image_shape(scene_handle)
    t = np.ascontiguousarray(targets, dtype=np.float32)
    if t.shape == shape[:-1] and shape[-1] == 1:
        t = t.reshape(shape)
    if t.shape != shape:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"reconstruct: targets have shape {t.shape} but the scene renders {shape} "
                    f"(views, H, W, C): one image per camera")
    return t


def reconstruct(ctx, scene, targets, volume, wrt, iterations, lr, optimizer, schedule, loss, tv,
                smoothness, tf_smoothness, batch, levels, init, init_value, seed, step, progress,
                checkpoint, resume, checkpoint_every, step_every, step_gamma, min_lr, tv_epsilon,
                mode, base_dir, workers=None):
    density, tf = _groups(wrt)
    lib = ctx._lib
    o = _capi.filled(
        _capi.ReconstructOptions, lib.ivr_reconstruct_options_init, _check, density=density,
        tf=tf, iterations=iterations,
        optimizer=_optional_choice(_OPTIMIZERS, optimizer, "optimizer"),
        schedule=_optional_choice(_SCHEDULES, schedule, "schedule"),
        loss=_optional_choice(_LOSSES, loss, "loss"), init=_optional_choice(_INITS, init, "init"),
        mode=_optional_choice(_MODES, mode, "mode"), lr=lr, tv=tv, smoothness=smoothness,
        tf_smoothness=tf_smoothness, batch=batch, levels=levels, seed=seed,
        init_value=init_value, step=step, tv_epsilon=tv_epsilon, step_every=step_every,
        step_gamma=step_gamma, min_lr=min_lr, precision=_PRECISIONS[ctx.precision])
    if resume and checkpoint is None:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    "reconstruct: resume=True needs checkpoint= (the prefix it was saved under)")
    prefix = os.fspath(checkpoint).encode() if checkpoint is not None else None

    # (workers (split, worker, workers, add, nz, weights): with nz the volume is the worker's slab)
    s = ctx._scene(scene, volume, base_dir, _slab_of(workers))
    try:
        t = _targets(ctx, s, targets)
        r = _capi.HANDLE()
        failure = []
        if workers is None:
            _check(lib.ivr_reconstruction_create(ctx._live(), s, t.ctypes.data_as(_FLOAT_P),
                                                 t.size, ctypes.byref(o), ctypes.byref(r)))
        else:  # (split, worker, workers, add, nz, weights): ivr.mpi.reconstruct; the sum lives
            # as long as `r`; weights: over views the workers' shares of each batch, over slabs
            # their shares of the planes (None: equal)
            split, worker, count, add, _, weights = workers
            sum_fn = _sum_fn(add, failure)
            _check(lib.ivr_reconstruction_create_weighted(
                ctx._live(), s, t.ctypes.data_as(_FLOAT_P), t.size, ctypes.byref(o), split,
                worker, count, _doubles(weights), sum_fn, None, ctypes.byref(r)))
    finally:
        lib.ivr_scene_release(s)
    try:
        if resume:
            _check(lib.ivr_reconstruction_resume(r, prefix))
        # Stepped from Python, not through ivr_reconstruction_run's callback: the progress
        # function's exceptions propagate as they are, and checkpoints may be written between
        # iterations (a callback must not call ivr on the same context).
        done, it, stopped = ctypes.c_int(), _capi.ReconstructIteration(), False
        while True:
            _check(lib.ivr_reconstruction_done(r, ctypes.byref(done)))
            if done.value:
                break
            status = lib.ivr_reconstruction_step(r, ctypes.byref(it))
            if failure:  # the workers' sum raised
                raise failure[0]
            _check(status)
            if prefix and checkpoint_every > 0 and it.iteration % checkpoint_every == 0:
                _check(lib.ivr_reconstruction_save_checkpoint(r, prefix))
            if progress is not None and progress(_entry(it)) is False:
                stopped = True
                break
        if prefix:
            _check(lib.ivr_reconstruction_save_checkpoint(r, prefix))
        return _outcome(lib, r, density, tf, stopped)
    finally:
        lib.ivr_reconstruction_release(r)


def _outcome(lib, r, density, tf, stopped):
    info = _capi.ReconstructInfo()
    _check(lib.ivr_reconstruction_info(r, ctypes.byref(info)))
    count = ctypes.c_size_t()
    _check(lib.ivr_reconstruction_history(r, None, 0, ctypes.byref(count)))
    history = (_capi.ReconstructIteration * max(count.value, 1))()
    _check(lib.ivr_reconstruction_history(r, history, len(history), ctypes.byref(count)))
    out = {"history": [_entry(h) for h in history[:count.value]], "iterations": info.iteration,
           "stopped": stopped, "optimizer": _OPTIMIZER_NAMES[info.optimizer], "lr": info.lr,
           "levels": info.levels}
    if density:
        shape = (ctypes.c_int64 * 3)()
        _check(lib.ivr_reconstruction_volume(r, None, 0, shape))
        v = np.empty(tuple(shape), dtype=np.float32)
        _check(lib.ivr_reconstruction_volume(r, v.ctypes.data_as(_FLOAT_P), v.size, shape))
        out["volume"] = v
    if tf:
        shape = (ctypes.c_int64 * 2)()
        _check(lib.ivr_reconstruction_tf(r, None, 0, shape))
        values = np.empty(tuple(shape), dtype=np.float64)
        _check(lib.ivr_reconstruction_tf(
            r, values.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), values.size, shape))
        out["tf"] = values
    return out


def _camera(c):
    cam = {"eye": list(c.eye), "target": list(c.target), "up": list(c.up), "fov_y": c.fov_y,
           "width": c.width, "height": c.height}
    if c.orthographic:
        cam.update(projection="orthographic", ortho_height=c.ortho_height)
    return cam


def viewpoint(ctx, scene, volume, view, iterations, lr, optimizer, step, progress, base_dir):
    lib = ctx._lib
    o = _capi.filled(
        _capi.ViewpointOptions, lib.ivr_viewpoint_options_init, _check, view=view,
        iterations=iterations, lr=lr, step=step,
        optimizer=_optional_choice(_OPTIMIZERS, optimizer, "optimizer"),
        precision=_PRECISIONS[ctx.precision])
    failure = []

    def call(entry, _user):
        e = entry.contents
        try:
            go = progress({"iteration": e.iteration, "entropy": e.entropy,
                           "azimuth": e.azimuth, "elevation": e.elevation})
            return 0 if go is False else 1
        except BaseException as error:  # noqa: BLE001 — re-raised once the C call returns
            failure.append(error)
            return 0

    callback = _capi.VIEWPOINT_PROGRESS(call) if progress else \
        ctypes.cast(None, _capi.VIEWPOINT_PROGRESS)
    history = (_capi.ViewpointStep * (max(o.iterations, 0) + 1))()
    result = _capi.ViewpointResult()
    s = ctx._scene(scene, volume, base_dir)
    try:
        status = lib.ivr_select_viewpoint(ctx._live(), s, ctypes.byref(o), callback, None,
                                          history, len(history), ctypes.byref(result))
        if failure:
            raise failure[0]
        _check(status)  # before the release below replaces the thread's last error
    finally:
        lib.ivr_scene_release(s)
    return {"camera": _camera(result.camera), "entropy_start": result.entropy_start,
            "entropy_best": result.entropy_best,
            "history": [{"iteration": h.iteration, "entropy": h.entropy, "azimuth": h.azimuth,
                         "elevation": h.elevation} for h in history[:result.iterations + 1]]}


def image_entropy(lib, image, background):
    a = np.ascontiguousarray(image, dtype=np.float32)
    if a.ndim == 3:
        a = a[np.newaxis]
    if a.ndim != 4:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"image_entropy: image must have shape (views, H, W, C) or (H, W, C), got "
                    f"{a.shape}")
    value = ctypes.c_double()
    _check(lib.ivr_image_entropy(a.ctypes.data_as(_FLOAT_P), (ctypes.c_int64 * 4)(*a.shape),
                                 float(background), ctypes.byref(value)))
    return value.value


def psnr(lib, image, reference):
    a = np.ascontiguousarray(image, dtype=np.float32)
    b = np.ascontiguousarray(reference, dtype=np.float32)
    if a.shape != b.shape:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"psnr: image {a.shape} and reference {b.shape} differ in shape")
    value = ctypes.c_double()
    _check(lib.ivr_psnr(a.ctypes.data_as(_FLOAT_P), b.ctypes.data_as(_FLOAT_P), a.size,
                        ctypes.byref(value)))
    return value.value
