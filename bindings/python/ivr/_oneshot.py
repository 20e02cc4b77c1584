"""_oneshot.py — ivr's module-level functions: each opens a Context for the one call (kernels come
from the on-disk cache after the first); use a Context's methods to keep one across calls."""
from . import Context


def project(scene, volume=None, precision="f32", device=None, base_dir=None):
    """Line integrals N v, float32 (views, H, W, 1): see Context.project."""
    with Context(device, precision) as c:
        return c.project(scene, volume, base_dir=base_dir)


def backproject(scene, lines, precision="f32", device=None, grid=None, base_dir=None):
    """N^T p, float32 (Z, Y, X): see Context.backproject."""
    with Context(device, precision) as c:
        return c.backproject(scene, lines, grid=grid, base_dir=base_dir)


def tomo(scene, lines, solver="cgls", iterations=50, nonneg=False, tv=0.0, tikhonov=0.0,
         tolerance=0.0, precision="f32", progress=None, device=None, **options):
    """(volume, history) reconstructed from line integrals: see Context.tomo."""
    with Context(device, precision) as c:
        return c.tomo(scene, lines, solver=solver, iterations=iterations, nonneg=nonneg, tv=tv,
                      tikhonov=tikhonov, tolerance=tolerance, progress=progress, **options)


def lines_from_intensities(scene, intensities, clamp=0.0, device=None, base_dir=None):
    """Line integrals from intensities: see Context.lines_from_intensities."""
    with Context(device) as c:
        return c.lines_from_intensities(scene, intensities, clamp=clamp, base_dir=base_dir)


def reconstruct(scene, targets, precision="f32", device=None, **options):
    """{"volume", "tf", "history", ...} recovered from images: see Context.reconstruct."""
    with Context(device, precision) as c:
        return c.reconstruct(scene, targets, **options)


def viewpoint(scene, precision="f32", device=None, **options):
    """{"camera", "entropy_start", "entropy_best", "history"}: see Context.viewpoint."""
    with Context(device, precision) as c:
        return c.viewpoint(scene, **options)
