"""ivr._tomo — Context.tomo (bindings/python/ivr/__init__.py): the solvers through ivr_tomo, or
through ivr_tomo_split for ivr.mpi.tomo's workers."""
import ctypes

import numpy as np

from . import (_capi, _check, _doubles, _optional_choice, _sum_fn, _FLOAT_P, _PRECISIONS,
               _SOLVERS)


def tomo(ctx, scene, lines, solver, iterations, nonneg, tv, tikhonov, tolerance, tv_epsilon,
         tv_reweight, relaxation, progress, grid, base_dir, info, _split):
    o = _capi.filled(
        _capi.TomoOptions, ctx._lib.ivr_tomo_options_init, _check,
        solver=_optional_choice(_SOLVERS, solver, "solver"),
        precision=_PRECISIONS[ctx.precision], iterations=iterations,
        nonneg=None if nonneg is None else bool(nonneg), tv_reweight=tv_reweight,
        tolerance=tolerance, tikhonov=tikhonov, tv=tv, tv_epsilon=tv_epsilon,
        relaxation=relaxation)
    failure = []

    def call(entry, _user):
        e = entry.contents
        try:
            go = progress({"iteration": e.iteration, "residual": e.residual,
                           "seconds": e.seconds})
            return 0 if go is False else 1
        except BaseException as error:  # noqa: BLE001 — re-raised once ivr_tomo returns
            failure.append(error)
            return 0

    callback = _capi.TOMO_PROGRESS(call) if progress else ctypes.cast(None, _capi.TOMO_PROGRESS)
    s = ctx._grid_scene(scene, grid, base_dir)
    try:
        p = ctx._rays(s, lines, "lines")
        out = ctx._volume_out(s)
        history = (_capi.TomoIteration * max(o.iterations, 1))()
        summary = _capi.TomoSummary()
        if _split is None:
            status = ctx._lib.ivr_tomo(ctx._live(), s, ctypes.byref(o),
                                        p.ctypes.data_as(_FLOAT_P), p.size,
                                        out.ctypes.data_as(_FLOAT_P), out.size, callback, None,
                                        history, len(history), ctypes.byref(summary))
        else:  # (split, rank, ranks, add, weights): ivr.mpi.tomo's workers, add(a) summing in
            # place; over slabs each worker's planes in proportion to its weight (None: equal)
            split, rank, ranks, add, weights = _split
            sum_fn = _sum_fn(add, failure)
            if split == 1:  # this worker's planes of the grid
                first, last = ctypes.c_int(), ctypes.c_int()
                _check(ctx._lib.ivr_domain_slab_weighted(out.shape[0], rank, ranks,
                                                          _doubles(weights), ctypes.byref(first),
                                                          ctypes.byref(last)))
                out = np.empty((last.value - first.value + 1,) + out.shape[1:],
                               dtype=np.float32)
            status = ctx._lib.ivr_tomo_split_weighted(
                ctx._live(), s, ctypes.byref(o), split, rank, ranks, _doubles(weights), sum_fn,
                None, p.ctypes.data_as(_FLOAT_P), p.size, out.ctypes.data_as(_FLOAT_P), out.size,
                callback, None, history, len(history), ctypes.byref(summary))
        if failure:
            raise failure[0]
        _check(status)  # before the release below replaces the thread's last error
    finally:
        ctx._lib.ivr_scene_release(s)
    if info is not None:
        info.update(stop_reason=summary.stop_reason.decode(), seconds=summary.seconds,
                    setup_seconds=summary.setup_seconds)
    return out, [{"iteration": h.iteration, "residual": h.residual, "seconds": h.seconds}
                 for h in history[:summary.iterations]]
