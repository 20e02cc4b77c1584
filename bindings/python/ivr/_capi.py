"""_capi.py — ctypes declarations of ivr's C API (include/ivr/ivr.h) and the library lookup:
$IVR_LIBRARY, else a libivr next to this package (or in the build tree beside it), else the
system loader."""
import ctypes
import ctypes.util
import os
from pathlib import Path

c_int64_p = ctypes.POINTER(ctypes.c_int64)


class _Handle(ctypes.Structure):
    pass


HANDLE = ctypes.POINTER(_Handle)


def filled(struct, init, check, /, **values):
    """An option struct filled by its init function (the library's defaults and its size), then
    the values given (None keeps the default), each as its field's C type: the defaults are
    the library's alone (bindings/python/tests/test_options.py checks the fields against ivr.h)."""
    options = struct()
    check(init(ctypes.byref(options)))
    types = dict(struct._fields_)
    for name, value in values.items():
        if value is not None:
            setattr(options, name, float(value) if types[name] is ctypes.c_double else int(value))
    return options


class TomoOptions(ctypes.Structure):
    """ivr_tomo_options"""
    _fields_ = [("size", ctypes.c_size_t), ("solver", ctypes.c_int), ("precision", ctypes.c_int),
                ("iterations", ctypes.c_int), ("nonneg", ctypes.c_int),
                ("tv_reweight", ctypes.c_int), ("tolerance", ctypes.c_double),
                ("tikhonov", ctypes.c_double), ("tv", ctypes.c_double),
                ("tv_epsilon", ctypes.c_double), ("relaxation", ctypes.c_double)]


class TomoIteration(ctypes.Structure):
    """ivr_tomo_iteration"""
    _fields_ = [("iteration", ctypes.c_int), ("residual", ctypes.c_double),
                ("seconds", ctypes.c_double)]


class TomoSummary(ctypes.Structure):
    """ivr_tomo_summary"""
    _fields_ = [("iterations", ctypes.c_int), ("stop_reason", ctypes.c_char_p),
                ("residual", ctypes.c_double), ("seconds", ctypes.c_double),
                ("setup_seconds", ctypes.c_double)]


TOMO_PROGRESS = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(TomoIteration), ctypes.c_void_p)
# ivr_sum_fn: a sum over the workers of a split operation, in place.
SUM_FN = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_double), ctypes.c_size_t,
                          ctypes.c_void_p)


class ReconstructOptions(ctypes.Structure):
    """ivr_reconstruct_options"""
    _fields_ = [("size", ctypes.c_size_t), ("density", ctypes.c_int), ("tf", ctypes.c_int),
                ("iterations", ctypes.c_int),
                ("optimizer", ctypes.c_int), ("lr", ctypes.c_double),
                ("schedule", ctypes.c_int), ("step_every", ctypes.c_int),
                ("step_gamma", ctypes.c_double), ("min_lr", ctypes.c_double),
                ("loss", ctypes.c_int), ("tv", ctypes.c_double), ("smoothness", ctypes.c_double),
                ("tf_smoothness", ctypes.c_double), ("tv_epsilon", ctypes.c_double),
                ("batch", ctypes.c_int), ("levels", ctypes.c_int), ("init", ctypes.c_int),
                ("init_value", ctypes.c_double), ("seed", ctypes.c_uint64),
                ("precision", ctypes.c_int), ("step", ctypes.c_double), ("mode", ctypes.c_int)]


class ReconstructIteration(ctypes.Structure):
    """ivr_reconstruct_iteration"""
    _fields_ = [("iteration", ctypes.c_int), ("level", ctypes.c_int), ("loss", ctypes.c_double),
                ("prior", ctypes.c_double), ("lr", ctypes.c_double),
                ("seconds", ctypes.c_double), ("views", ctypes.c_int)]


class ReconstructInfo(ctypes.Structure):
    """ivr_reconstruct_info"""
    _fields_ = [("iteration", ctypes.c_int), ("iterations", ctypes.c_int),
                ("levels", ctypes.c_int), ("optimizer", ctypes.c_int), ("lr", ctypes.c_double)]


class ViewpointOptions(ctypes.Structure):
    """ivr_viewpoint_options"""
    _fields_ = [("size", ctypes.c_size_t), ("view", ctypes.c_int), ("iterations", ctypes.c_int),
                ("optimizer", ctypes.c_int), ("lr", ctypes.c_double),
                ("precision", ctypes.c_int), ("step", ctypes.c_double)]


class ViewpointStep(ctypes.Structure):
    """ivr_viewpoint_step"""
    _fields_ = [("iteration", ctypes.c_int), ("entropy", ctypes.c_double),
                ("azimuth", ctypes.c_double), ("elevation", ctypes.c_double)]


class Camera(ctypes.Structure):
    """ivr_camera"""
    _fields_ = [("eye", ctypes.c_double * 3), ("target", ctypes.c_double * 3),
                ("up", ctypes.c_double * 3), ("fov_y", ctypes.c_double),
                ("orthographic", ctypes.c_int), ("ortho_height", ctypes.c_double),
                ("width", ctypes.c_int), ("height", ctypes.c_int)]


class ViewpointResult(ctypes.Structure):
    """ivr_viewpoint_result"""
    _fields_ = [("camera", Camera), ("entropy_start", ctypes.c_double),
                ("entropy_best", ctypes.c_double), ("iterations", ctypes.c_int)]


VIEWPOINT_PROGRESS = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ViewpointStep),
                                      ctypes.c_void_p)


class SessionOptions(ctypes.Structure):
    """ivr_session_options"""
    _fields_ = [("size", ctypes.c_size_t), ("precision", ctypes.c_int), ("step", ctypes.c_double),
                ("empty_space", ctypes.c_int), ("min_empty_fraction", ctypes.c_double),
                ("brick_size", ctypes.c_int)]


class OperationStats(ctypes.Structure):
    """ivr_operation_stats"""
    _fields_ = [("kernel_seconds", ctypes.c_double), ("build_seconds", ctypes.c_double),
                ("samples", ctypes.c_uint64), ("device_bytes", ctypes.c_uint64),
                ("step", ctypes.c_double), ("skipped_empty", ctypes.c_int),
                ("empty_fraction", ctypes.c_double)]


def _candidates():
    env = os.environ.get("IVR_LIBRARY")
    if env:
        yield env
        return
    here = Path(__file__).resolve().parent
    for folder in (here, here.parent, here.parent.parent.parent / "build"):
        for name in ("libivr.so.0", "libivr.so", "libivr.dylib"):
            path = folder / name
            if path.exists():
                yield str(path)
    found = ctypes.util.find_library("ivr")
    if found:
        yield found


def load():
    errors = []
    for path in _candidates():
        try:
            lib = ctypes.CDLL(path)
        except OSError as e:
            errors.append(f"{path}: {e}")
            continue
        _declare(lib)
        return lib
    hint = ""
    if any("libOpenCL" in e for e in errors):  # libivr is there, the ICD loader is not
        hint = " (libOpenCL.so.1, the OpenCL ICD loader: Debian's ocl-icd-libopencl1)"
    raise OSError("libivr not found or not loadable" + hint + " (set IVR_LIBRARY to its path)" +
                  ("; tried " + "; ".join(errors) if errors else ""))


def _declare(lib):
    S = ctypes.c_int  # ivr_status
    pp = ctypes.POINTER(HANDLE)
    fp = ctypes.POINTER(ctypes.c_float)
    sigs = {
        "ivr_status_string": (ctypes.c_char_p, [ctypes.c_int]),
        "ivr_version": (ctypes.c_int, []),
        "ivr_last_error": (ctypes.c_char_p, []),
        "ivr_last_opencl_error": (ctypes.c_int, []),
        "ivr_devices_json": (S, [ctypes.c_char_p, ctypes.c_size_t,
                                 ctypes.POINTER(ctypes.c_size_t)]),
        "ivr_context_create": (S, [ctypes.c_char_p, pp]),
        "ivr_context_retain": (S, [HANDLE]),
        "ivr_context_release": (S, [HANDLE]),
        "ivr_context_last_error": (ctypes.c_char_p, [HANDLE]),
        "ivr_context_device_name": (S, [HANDLE, ctypes.POINTER(ctypes.c_char_p)]),
        "ivr_scene_from_json": (S, [HANDLE, ctypes.c_char_p, ctypes.c_char_p, pp]),
        "ivr_scene_load": (S, [HANDLE, ctypes.c_char_p, pp]),
        "ivr_scene_retain": (S, [HANDLE]),
        "ivr_scene_release": (S, [HANDLE]),
        "ivr_scene_set_volume": (S, [HANDLE, ctypes.c_void_p, ctypes.c_int, c_int64_p]),
        "ivr_scene_image_shape": (S, [HANDLE, c_int64_p]),
        "ivr_scene_set_rays": (S, [HANDLE, ctypes.POINTER(ctypes.c_double), ctypes.c_size_t,
                                   ctypes.c_int]),
        "ivr_scene_ray_count": (S, [HANDLE, ctypes.POINTER(ctypes.c_size_t)]),
        "ivr_scene_volume_shape": (S, [HANDLE, c_int64_p]),
        "ivr_scene_step": (S, [HANDLE, HANDLE, ctypes.c_int, ctypes.POINTER(ctypes.c_double),
                               ctypes.POINTER(ctypes.c_double)]),
        "ivr_render": (S, [HANDLE, HANDLE, ctypes.c_int, ctypes.c_double,
                           ctypes.POINTER(ctypes.c_float), ctypes.c_size_t]),
        "ivr_gradient": (S, [HANDLE, HANDLE, ctypes.POINTER(ctypes.c_float), ctypes.c_size_t,
                             ctypes.c_char_p, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                             ctypes.c_double, pp]),
        "ivr_image_loss": (S, [ctypes.POINTER(ctypes.c_float), ctypes.POINTER(ctypes.c_float),
                               ctypes.c_size_t, ctypes.c_int, ctypes.POINTER(ctypes.c_double)]),
        "ivr_jacobian": (S, [HANDLE, HANDLE, ctypes.c_char_p, ctypes.c_int, ctypes.c_double, pp]),
        "ivr_volume_from_json": (S, [HANDLE, ctypes.c_char_p, ctypes.c_char_p, pp]),
        "ivr_volume_release": (S, [HANDLE]),
        "ivr_volume_shape": (S, [HANDLE, c_int64_p]),
        "ivr_volume_data": (S, [HANDLE, ctypes.POINTER(ctypes.c_float), ctypes.c_size_t]),
        "ivr_result_retain": (S, [HANDLE]),
        "ivr_result_release": (S, [HANDLE]),
        "ivr_result_info": (S, [HANDLE, ctypes.POINTER(ctypes.c_double),
                                ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_double)]),
        "ivr_result_array_count": (S, [HANDLE, ctypes.POINTER(ctypes.c_size_t)]),
        "ivr_result_array_shape": (S, [HANDLE, ctypes.c_size_t, ctypes.POINTER(ctypes.c_char_p),
                                       ctypes.POINTER(ctypes.c_int), c_int64_p]),
        "ivr_result_array_data": (S, [HANDLE, ctypes.c_size_t, ctypes.POINTER(ctypes.c_double),
                                      ctypes.c_size_t]),
        "ivr_project": (S, [HANDLE, HANDLE, ctypes.c_int, fp, ctypes.c_size_t, fp,
                            ctypes.c_size_t]),
        "ivr_backproject": (S, [HANDLE, HANDLE, ctypes.c_int, fp, ctypes.c_size_t, fp,
                                ctypes.c_size_t]),
        "ivr_tomo_options_init": (S, [ctypes.POINTER(TomoOptions)]),
        "ivr_tomo": (S, [HANDLE, HANDLE, ctypes.POINTER(TomoOptions), fp, ctypes.c_size_t, fp,
                         ctypes.c_size_t, TOMO_PROGRESS, ctypes.c_void_p,
                         ctypes.POINTER(TomoIteration), ctypes.c_size_t,
                         ctypes.POINTER(TomoSummary)]),
        "ivr_render_slabs": (S, [HANDLE, HANDLE, ctypes.c_int, ctypes.c_double, ctypes.c_int,
                                 ctypes.c_int, SUM_FN, ctypes.c_void_p, fp, ctypes.c_size_t]),
        "ivr_gradient_shared": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t, ctypes.c_char_p,
                                    ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_double,
                                    ctypes.c_int, ctypes.c_int, ctypes.c_int, SUM_FN,
                                    ctypes.c_void_p, pp]),
        "ivr_gradient_shared_weighted": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t,
                                             ctypes.c_char_p, ctypes.c_int, ctypes.c_int,
                                             ctypes.c_int, ctypes.c_double, ctypes.c_int,
                                             ctypes.c_int, ctypes.c_int,
                                             ctypes.POINTER(ctypes.c_double), SUM_FN,
                                             ctypes.c_void_p, pp]),
        "ivr_view_shares": (S, [ctypes.c_size_t, ctypes.POINTER(ctypes.c_double), ctypes.c_size_t,
                                ctypes.c_int, ctypes.POINTER(ctypes.c_size_t)]),
        "ivr_context_samples_per_second": (S, [HANDLE, ctypes.POINTER(ctypes.c_double)]),
        "ivr_gradient_slabs": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t, ctypes.c_char_p,
                                   ctypes.c_int, ctypes.c_int, ctypes.c_double, ctypes.c_int,
                                   ctypes.c_int, SUM_FN, ctypes.c_void_p, pp]),
        "ivr_scene_set_volume_slab": (S, [HANDLE, ctypes.c_void_p, ctypes.c_int,
                                          ctypes.POINTER(ctypes.c_int64), ctypes.c_int64,
                                          ctypes.c_int, ctypes.c_int]),
        "ivr_render_split": (S, [HANDLE, HANDLE, ctypes.c_int, ctypes.c_double, ctypes.c_int,
                                 ctypes.c_int, ctypes.c_int, SUM_FN, ctypes.c_void_p, fp,
                                 ctypes.c_size_t]),
        "ivr_gradient_split": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t, ctypes.c_char_p,
                                   ctypes.c_int, ctypes.c_int, ctypes.c_double, ctypes.c_int,
                                   ctypes.c_int, ctypes.c_int, SUM_FN, ctypes.c_void_p, pp]),
        "ivr_tomo_split": (S, [HANDLE, HANDLE, ctypes.POINTER(TomoOptions), ctypes.c_int,
                               ctypes.c_int, ctypes.c_int, SUM_FN, ctypes.c_void_p, fp,
                               ctypes.c_size_t, fp, ctypes.c_size_t, TOMO_PROGRESS,
                               ctypes.c_void_p, ctypes.POINTER(TomoIteration), ctypes.c_size_t,
                               ctypes.POINTER(TomoSummary)]),
        "ivr_domain_slab": (S, [ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int)]),
        "ivr_domain_slab_weighted": (S, [ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                         ctypes.POINTER(ctypes.c_double),
                                         ctypes.POINTER(ctypes.c_int),
                                         ctypes.POINTER(ctypes.c_int)]),
        "ivr_scene_set_volume_slab_weighted": (S, [HANDLE, ctypes.c_void_p, ctypes.c_int,
                                                   ctypes.POINTER(ctypes.c_int64), ctypes.c_int64,
                                                   ctypes.c_int, ctypes.c_int,
                                                   ctypes.POINTER(ctypes.c_double)]),
        "ivr_render_split_weighted": (S, [HANDLE, HANDLE, ctypes.c_int, ctypes.c_double,
                                          ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                          ctypes.POINTER(ctypes.c_double), SUM_FN,
                                          ctypes.c_void_p, fp, ctypes.c_size_t]),
        "ivr_gradient_split_weighted": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t, ctypes.c_char_p,
                                            ctypes.c_int, ctypes.c_int, ctypes.c_double,
                                            ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                            ctypes.POINTER(ctypes.c_double), SUM_FN,
                                            ctypes.c_void_p, pp]),
        "ivr_gradient_split_deterministic": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t,
                                                 ctypes.c_char_p, ctypes.c_int, ctypes.c_int,
                                                 ctypes.c_double, ctypes.c_int, ctypes.c_int,
                                                 ctypes.c_int, ctypes.c_int,
                                                 ctypes.POINTER(ctypes.c_double), SUM_FN,
                                                 ctypes.c_void_p, pp]),
        "ivr_tomo_split_weighted": (S, [HANDLE, HANDLE, ctypes.POINTER(TomoOptions), ctypes.c_int,
                                        ctypes.c_int, ctypes.c_int,
                                        ctypes.POINTER(ctypes.c_double), SUM_FN, ctypes.c_void_p,
                                        fp, ctypes.c_size_t, fp, ctypes.c_size_t, TOMO_PROGRESS,
                                        ctypes.c_void_p, ctypes.POINTER(TomoIteration),
                                        ctypes.c_size_t, ctypes.POINTER(TomoSummary)]),
        "ivr_lines_from_intensities": (S, [HANDLE, fp, ctypes.c_size_t, ctypes.c_double, fp,
                                           ctypes.c_size_t]),
        "ivr_phantom": (S, [ctypes.c_char_p, ctypes.c_int, ctypes.c_uint64, ctypes.c_int, fp,
                            ctypes.c_size_t]),
        "ivr_reconstruct_options_init": (S, [ctypes.POINTER(ReconstructOptions)]),
        "ivr_reconstruction_create": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t,
                                          ctypes.POINTER(ReconstructOptions), pp]),
        "ivr_reconstruction_create_shared": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t,
                                                 ctypes.POINTER(ReconstructOptions), ctypes.c_int,
                                                 ctypes.c_int, SUM_FN, ctypes.c_void_p, pp]),
        "ivr_reconstruction_create_split": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t,
                                                ctypes.POINTER(ReconstructOptions), ctypes.c_int,
                                                ctypes.c_int, ctypes.c_int, SUM_FN,
                                                ctypes.c_void_p, pp]),
        "ivr_reconstruction_create_weighted": (S, [HANDLE, HANDLE, fp, ctypes.c_size_t,
                                                   ctypes.POINTER(ReconstructOptions),
                                                   ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                                   ctypes.POINTER(ctypes.c_double), SUM_FN,
                                                   ctypes.c_void_p, pp]),
        "ivr_reconstruction_release": (S, [HANDLE]),
        "ivr_reconstruction_step": (S, [HANDLE, ctypes.POINTER(ReconstructIteration)]),
        "ivr_reconstruction_done": (S, [HANDLE, ctypes.POINTER(ctypes.c_int)]),
        "ivr_reconstruction_info": (S, [HANDLE, ctypes.POINTER(ReconstructInfo)]),
        "ivr_reconstruction_history": (S, [HANDLE, ctypes.POINTER(ReconstructIteration),
                                           ctypes.c_size_t, ctypes.POINTER(ctypes.c_size_t)]),
        "ivr_reconstruction_volume": (S, [HANDLE, fp, ctypes.c_size_t, c_int64_p]),
        "ivr_reconstruction_tf": (S, [HANDLE, ctypes.POINTER(ctypes.c_double), ctypes.c_size_t,
                                      c_int64_p]),
        "ivr_reconstruction_save_checkpoint": (S, [HANDLE, ctypes.c_char_p]),
        "ivr_reconstruction_resume": (S, [HANDLE, ctypes.c_char_p]),
        "ivr_viewpoint_options_init": (S, [ctypes.POINTER(ViewpointOptions)]),
        "ivr_select_viewpoint": (S, [HANDLE, HANDLE, ctypes.POINTER(ViewpointOptions),
                                     VIEWPOINT_PROGRESS, ctypes.c_void_p,
                                     ctypes.POINTER(ViewpointStep), ctypes.c_size_t,
                                     ctypes.POINTER(ViewpointResult)]),
        "ivr_image_entropy": (S, [fp, c_int64_p, ctypes.c_double,
                                  ctypes.POINTER(ctypes.c_double)]),
        "ivr_psnr": (S, [fp, fp, ctypes.c_size_t, ctypes.POINTER(ctypes.c_double)]),
        "ivr_tf_from_json": (S, [HANDLE, ctypes.c_char_p, pp]),
        "ivr_tf_retain": (S, [HANDLE]),
        "ivr_tf_release": (S, [HANDLE]),
        # device-resident sessions and device arrays (c_api_session.cpp)
        "ivr_array_create": (S, [HANDLE, ctypes.c_int, c_int64_p, ctypes.c_int, pp]),
        "ivr_array_retain": (S, [HANDLE]),
        "ivr_array_release": (S, [HANDLE]),
        "ivr_array_name": (S, [HANDLE, ctypes.POINTER(ctypes.c_char_p)]),
        "ivr_array_info": (S, [HANDLE, ctypes.POINTER(ctypes.c_int), c_int64_p,
                               ctypes.POINTER(ctypes.c_int)]),
        "ivr_array_upload": (S, [HANDLE, ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]),
        "ivr_array_download": (S, [HANDLE, ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]),
        "ivr_array_wait": (S, [HANDLE]),
        "ivr_array_wrap": (S, [HANDLE, ctypes.c_void_p, ctypes.c_int, c_int64_p, ctypes.c_int,
                               ctypes.POINTER(ctypes.c_int), pp]),
        "ivr_array_map": (S, [HANDLE, ctypes.POINTER(ctypes.c_void_p)]),
        "ivr_array_unmap": (S, [HANDLE]),
        "ivr_session_options_init": (S, [ctypes.POINTER(SessionOptions)]),
        "ivr_session_create": (S, [HANDLE, HANDLE, ctypes.POINTER(SessionOptions), pp]),
        "ivr_session_retain": (S, [HANDLE]),
        "ivr_session_release": (S, [HANDLE]),
        "ivr_session_set_volume": (S, [HANDLE, ctypes.c_void_p, ctypes.c_int, c_int64_p]),
        "ivr_session_set_volume_array": (S, [HANDLE, HANDLE]),
        "ivr_session_set_tf": (S, [HANDLE, HANDLE]),
        "ivr_session_set_cameras_json": (S, [HANDLE, ctypes.c_char_p]),
        "ivr_session_set_cameras": (S, [HANDLE, ctypes.POINTER(Camera), ctypes.c_size_t]),
        "ivr_session_set_rays": (S, [HANDLE, ctypes.POINTER(ctypes.c_double), ctypes.c_size_t,
                                     ctypes.c_int]),
        "ivr_session_set_integrator_json": (S, [HANDLE, ctypes.c_char_p]),
        "ivr_session_set_background": (S, [HANDLE, ctypes.POINTER(ctypes.c_double)]),
        "ivr_session_set_target": (S, [HANDLE, fp, ctypes.c_size_t]),
        "ivr_session_set_target_array": (S, [HANDLE, HANDLE]),
        "ivr_session_image_shape": (S, [HANDLE, c_int64_p]),
        "ivr_session_volume_shape": (S, [HANDLE, c_int64_p]),
        "ivr_session_volume": (S, [HANDLE, pp]),
        "ivr_session_render": (S, [HANDLE, pp]),
        "ivr_session_gradient": (S, [HANDLE, HANDLE, ctypes.c_char_p, ctypes.c_int, ctypes.c_int,
                                     ctypes.c_int, pp, pp, ctypes.c_size_t,
                                     ctypes.POINTER(ctypes.c_size_t),
                                     ctypes.POINTER(ctypes.c_int)]),
        "ivr_session_jacobian": (S, [HANDLE, ctypes.c_char_p, pp]),
        "ivr_session_project": (S, [HANDLE, HANDLE, pp]),
        "ivr_session_backproject": (S, [HANDLE, HANDLE, pp]),
        "ivr_session_loss": (S, [HANDLE, HANDLE, HANDLE, ctypes.c_int, pp]),
        "ivr_density_optimizer_create": (S, [HANDLE, ctypes.c_int, ctypes.c_double, pp]),
        "ivr_density_optimizer_retain": (S, [HANDLE]),
        "ivr_density_optimizer_release": (S, [HANDLE]),
        "ivr_session_step": (S, [HANDLE, HANDLE, HANDLE]),
        "ivr_session_last_stats": (S, [HANDLE, ctypes.POINTER(OperationStats)]),
        "ivr_session_finish": (S, [HANDLE]),
    }
    for name, (restype, argtypes) in sigs.items():
        f = getattr(lib, name)
        f.restype = restype
        f.argtypes = argtypes
