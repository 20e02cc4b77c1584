"""ivr.mpi — ivr under MPI from Python (mpi4py): data-parallel over views, as `mpirun -np N ivr
render|gradient|project|backproject|tomo` (docs/scaling.md), and domain-parallel over slabs of
z planes (`render`, `gradient`, `tomo` and `reconstruct` with split="slabs", as `--split slabs`;
`render`, `gradient` and `reconstruct` also with split="segments", each ray's slab segments
marched at once and composited in order, as `--split segments`);
and `reconstruct`, each batch's views shared out (as `mpirun -np N ivr reconstruct`). Each rank renders or differentiates its contiguous share of the
views (a ray list: of the rays) with the whole volume; the images are gathered in view order, the
loss and the gradients weighted by the shares' sizes (mse, l1: the mean losses; dot: summed) and
summed over the ranks (the gradient through the C API's ivr_gradient_shared; with
deterministic=True the density gradient is one process's bit for bit), as are the back-projections of the shares' lines, the per-view groups (camera, rays) gathered in view order. Every rank gets
the whole result, which equals one process's to rounding.

    from mpi4py import MPI
    import ivr, ivr.mpi
    ctx = ivr.Context(precision="f64")
    loss, grads = ivr.mpi.gradient(ctx, scene, volume, target, wrt=("density", "tf"))

Over views each rank's share is in proportion to its device's speed (ctx.samples_per_second,
gathered from every rank: ranks on one machine split equally), or to shares=[w0, w1, …] (one
weight a rank, every rank passing the same), every rank at least one view where there are as many
views as ranks (view_shares_by(each=True), as `mpirun ivr` splits them). Over slabs and segments
the same weights size each rank's slab of z planes (every rank at least one cell: the C API's
ivr_domain_slab_weighted, as `mpirun ivr --split slabs`), so that a fast device's longer slab
takes about as long as a slow one's; ivr.mpi.slab(nz, ctx=ctx, shares=…) gives a rank's planes.

Run with `mpirun -np N python3 -m mpi4py script.py` (an exception on one rank then aborts every
rank instead of leaving the others waiting in a collective); `comm` defaults to MPI.COMM_WORLD. The scene is a dict
(or its JSON text) whose "cameras" list, or in-memory "rays" array, is shared out.
"""
import json

import numpy as np

from . import Error, ray_array, view_shares_by


def _comm(comm):
    if comm is None:
        from mpi4py import MPI
        comm = MPI.COMM_WORLD
    return comm


def view_shares(n, parts):
    """[(first, count)]: n views cut into at most `parts` contiguous near-equal shares (the first
    n % parts one longer), as the C++ view_shares(); empty shares are left out."""
    if n < 0 or parts < 1:
        raise Error("IVR_ERROR_INVALID_ARGUMENT", f"view_shares: {n} views over {parts} parts")
    return [s for s in view_shares_by(n, [1.0] * parts, each=False) if s[1]]


def _scene_dict(scene):
    if isinstance(scene, str):
        scene = json.loads(scene)
    if not isinstance(scene, dict):
        raise Error("IVR_ERROR_INVALID_ARGUMENT", "ivr.mpi: the scene must be a dict or its JSON text")
    return scene


def _items(scene):
    """How many views (or rays of an in-memory ray list) the scene has."""
    if "rays" in scene:
        if isinstance(scene["rays"], dict):
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        "ivr.mpi: give the scene's rays as an array (not a file) to share them out")
        return len(ray_array(scene["rays"]))
    cameras = scene.get("cameras")
    if not isinstance(cameras, list) or not cameras:
        raise Error("IVR_ERROR_INVALID_ARGUMENT", "ivr.mpi: the scene has no \"cameras\" list")
    return len(cameras)


def scene_share(scene, first, count):
    """The scene with views (or rays) first … first + count − 1 alone."""
    scene = _scene_dict(scene)
    out = dict(scene)
    if "rays" in scene:
        out["rays"] = ray_array(scene["rays"])[first:first + count]
    else:
        out["cameras"] = scene["cameras"][first:first + count]
    return out


def rank_weights(ctx, comm=None, shares=None):
    """Every rank's weight, its share of the views or of the planes in proportion
    (docs/scaling.md): `shares`, one a rank (every rank passing the same), else each rank's
    ctx.samples_per_second — its device's speed on its own machine — gathered from every rank
    (collective)."""
    comm = _comm(comm)
    if shares is None:
        return comm.allgather(float(ctx.samples_per_second))
    shares = [float(w) for w in shares]
    if len(shares) != comm.Get_size():
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"ivr.mpi: shares has {len(shares)} weights for {comm.Get_size()} ranks")
    return shares


def _counts(ctx, comm, n, shares):
    """Every rank's count of n views by rank_weights, each at least one where n >= ranks (the
    ranks' split of `mpirun ivr`)."""
    return [c for _, c in view_shares_by(n, rank_weights(ctx, comm, shares), each=True)]


def _mine(ctx, comm, n, shares):
    """This rank's (first, count), or None where it has no share (more ranks than views)."""
    counts = _counts(ctx, comm, n, shares)
    rank = comm.Get_rank()
    return (sum(counts[:rank]), counts[rank]) if counts[rank] else None


def _worker_weights(counts):
    """The ranks' counts as the workers' weights, which split the same n back into them exactly
    (None: equal, which is what a count of 0 — fewer views than ranks — means)."""
    return None if 0 in counts else [float(c) for c in counts]


def slab(nz, comm=None, ctx=None, shares=None):
    """(first, last): the z planes of a volume of nz planes that this rank holds over slabs (the C
    API's ivr_domain_slab_weighted) — what to load and pass as `volume` with nz=… to render,
    gradient and reconstruct over slabs or segments, so that no rank holds the whole volume. The
    planes follow the ranks' weights as those calls weigh them: pass the same ctx (each rank's
    speed, gathered: collective) or shares."""
    import ctypes
    from . import _check, _doubles, _library
    comm = _comm(comm)
    if ctx is None and shares is None:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    "ivr.mpi.slab: pass ctx= (the ranks' speeds, which render, gradient and "
                    "reconstruct weigh the slabs by) or shares=")
    weights = rank_weights(ctx, comm, shares)
    first, last = ctypes.c_int(), ctypes.c_int()
    _check(_library().ivr_domain_slab_weighted(int(nz), comm.Get_rank(), comm.Get_size(),
                                               _doubles(weights), ctypes.byref(first),
                                               ctypes.byref(last)))
    return first.value, last.value


def _slab_split(code, comm, nz, weights):
    """(split, rank, ranks, add, nz, weights): a worker over slabs or segments (weights: the
    ranks', sizing their slabs), or over views (weights: the batches' shares)."""
    return (code, comm.Get_rank(), comm.Get_size(), _summer(comm), None if nz is None else int(nz),
            weights)


def _complete_shared_planes(comm, part):
    """This rank's planes of a slab-split density gradient with the planes it shares with its
    neighbours completed by their parts (each shared plane the two ranks' sum, on both)."""
    ends = comm.allgather((part[:1].copy(), part[-1:].copy()))
    rank, out = comm.Get_rank(), part.copy()
    if rank > 0:
        out[:1] += ends[rank - 1][1]
    if rank + 1 < len(ends):
        out[-1:] += ends[rank + 1][0]
    return out


def _whole_volume(nz, where):
    if nz is not None:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"ivr.mpi.{where}: nz (a rank's slab for a volume) applies over slabs or "
                    f"segments; over views every rank holds the whole volume")


def _summer(comm):
    """add(a): `a` (float64) replaced by its sum over the ranks (MPI_Allreduce)."""
    from mpi4py import MPI

    def add(a):  # (a may view the library's doubles: its buffer format is named explicitly)
        total = np.empty(a.shape, dtype=np.float64)
        comm.Allreduce([a, MPI.DOUBLE], [total, MPI.DOUBLE], op=MPI.SUM)
        a[:] = total
    return add


_SPLITS = {"views": 0, "slabs": 1, "segments": 2}  # (the C API's ivr_split)


def _check_split(split, where, allowed=("views", "slabs", "segments")):
    if split not in allowed:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"ivr.mpi.{where}: split {split!r} ({', '.join(allowed[:-1])} or {allowed[-1]})")
    return _SPLITS[split]


def render(ctx, scene, volume=None, comm=None, split="views", nz=None, shares=None, **options):
    """ctx.render of the whole scene, each rank rendering its share: every rank gets the images of
    every view (views, H, W, C) (a ray list: (rays, C)). split="slabs": each rank marches one slab
    of z planes of the volume on its device, the rays' march states passed between the ranks (the
    whole volume is given on every rank; the device holds its slab). split="segments": each rank
    marches its slab's segment of every ray at once, the segments exchanged once and composited in
    order (early termination then stops a segment only on its own transmittance: docs/scaling.md).
    Over slabs or segments with nz=NZ, `volume` is this rank's planes ivr.mpi.slab(NZ, ctx=ctx,
    shares=shares) alone (planes, ny, nx): no rank holds the whole volume. Each rank's share of
    the views, or of the planes, follows rank_weights(ctx, comm, shares). `options` are
    ctx.render's."""
    comm = _comm(comm)
    scene = _scene_dict(scene)
    code = _check_split(split, "render")
    if split != "views":
        return ctx.render(scene, volume, **options,
                          _split=_slab_split(code, comm, nz, rank_weights(ctx, comm, shares)))
    _whole_volume(nz, "render")
    mine = _mine(ctx, comm, _items(scene), shares)
    image = ctx.render(scene_share(scene, *mine), volume, **options) if mine else None
    return np.concatenate([p for p in comm.allgather(image) if p is not None], axis=0)


def project(ctx, scene, volume=None, comm=None, shares=None, **options):
    """ctx.project of the whole scene, each rank projecting its share of the views: every rank gets
    the line integrals of every view (views, H, W, 1) (a ray list: (rays, 1))."""
    comm = _comm(comm)
    scene = _scene_dict(scene)
    mine = _mine(ctx, comm, _items(scene), shares)
    lines = ctx.project(scene_share(scene, *mine), volume, **options) if mine else None
    return np.concatenate([p for p in comm.allgather(lines) if p is not None], axis=0)


def backproject(ctx, scene, lines, comm=None, shares=None, **options):
    """ctx.backproject of the whole scene's `lines` (first axis: views, or a ray list's rays), each
    rank back-projecting its share: every rank gets N^T p (Z, Y, X), the parts summed in float64
    and rounded to float32 once, as ctx.backproject returns it."""
    comm = _comm(comm)
    scene = _scene_dict(scene)
    n = _items(scene)
    lines = np.asarray(lines)
    if lines.shape[0] != n:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"ivr.mpi.backproject: lines has {lines.shape[0]} rows on its first axis but "
                    f"the scene has {n} views or rays")
    mine = _mine(ctx, comm, n, shares)
    first, count = mine if mine else (0, 1)  # (a rank without a share adds zeros)
    part = lines[first:first + count] if mine else np.zeros_like(lines[:1])
    volume = np.ascontiguousarray(
        ctx.backproject(scene_share(scene, first, count), part, **options), dtype=np.float64)
    from mpi4py import MPI
    summed = np.empty_like(volume)
    comm.Allreduce(volume, summed, op=MPI.SUM)
    return summed.astype(np.float32)


def gradient(ctx, scene, volume, target, wrt=("density",), loss="mse", comm=None, split="views",
             nz=None, gather=True, shares=None, **options):
    """ctx.gradient of the whole scene, each rank differentiating its share of the views (the
    target's first axis: views, or a ray list's rays): every rank gets (loss, {group: array}), one
    process's result to rounding. split="slabs" (every scheme): each rank differentiates over one
    slab of z planes, the slabs' density parts joined (shared planes added) and the TF parts
    summed; background and the forward lanes' groups (camera, …) come whole on every rank.
    split="segments": the same over independent segments (the camera's tangents composited). Over
    slabs or segments each rank's planes follow rank_weights(ctx, comm, shares); with nz=NZ,
    `volume` is this rank's planes ivr.mpi.slab(NZ, ctx=ctx, shares=shares) alone; with
    gather=False "density" is this rank's planes (the planes it shares with a neighbour complete)
    instead of the whole grid on every rank.
    `options` are ctx.gradient's (mode, step, base_dir, deterministic — the density gradient
    summed in fixed point: one process's bits over views and over slabs (the midpoint, trapezoid
    and preintegrated schemes); over slabs mode is not taken: density, tf and background by the
    adjoint, the others forward)."""
    comm = _comm(comm)
    scene = _scene_dict(scene)
    code = _check_split(split, "gradient")
    if split != "views":
        weights = rank_weights(ctx, comm, shares)
        value, arrays = ctx.gradient(scene, volume, target, wrt=wrt, loss=loss,
                                     _split=_slab_split(code, comm, nz, weights), **options)
        out = {}
        for name, a in arrays.items():
            a = np.ascontiguousarray(a, dtype=np.float64)
            if name == "density" and not gather:
                out[name] = _complete_shared_planes(comm, a)
            elif name == "density":  # the slabs in rank order, each shared plane the two parts' sum
                parts = comm.allgather(a)
                whole = parts[0]
                for p in parts[1:]:
                    whole = np.concatenate([whole[:-1], whole[-1:] + p[:1], p[1:]], axis=0)
                out[name] = whole
            elif name == "tf":
                summed = np.empty_like(a)
                from mpi4py import MPI
                comm.Allreduce(a, summed, op=MPI.SUM)
                out[name] = summed
            else:
                out[name] = a
        return value, out
    _whole_volume(nz, "gradient")
    n = _items(scene)
    target = np.asarray(target, dtype=np.float32)
    if n > 1 and target.shape[0] != n:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"ivr.mpi.gradient: target has {target.shape[0]} rows on its first axis but "
                    f"the scene has {n} views or rays")
    # Every rank a worker of the data-parallel gradient (ivr_gradient_shared): its share of the
    # views differentiated, the shares combined through the communicator's sum.
    weights = _worker_weights(_counts(ctx, comm, n, shares))
    return ctx.gradient(scene, volume, target, wrt=wrt, loss=loss,
                        _shared=(comm.Get_rank(), comm.Get_size(), _summer(comm), weights),
                        **options)


def tomo(ctx, scene, lines, comm=None, split="views", shares=None, **options):
    """(volume, history): ctx.tomo (CGLS, with nonneg or tikhonov) of the whole scene's `lines`
    (first axis: views, or a ray list's rays) by every rank together; every rank gets the whole
    volume (Z, Y, X) float32, one process's to rounding. split="views": each rank its share of the
    views and their lines, the volume whole on every rank (N^T r and the dot products over lines
    summed, MPI_Allreduce); split="slabs": each rank one slab of z planes of the iterate and every
    line (N x summed over the ranks, the shared planes joined), the slabs gathered at the end. Each
    rank's share of the views or of the planes follows rank_weights(ctx, comm, shares).
    `options` are ctx.tomo's (iterations, nonneg, tikhonov, tolerance, progress, grid, info)."""
    comm = _comm(comm)
    scene = _scene_dict(scene)
    _check_split(split, "tomo", ("views", "slabs"))  # (a line's slab parts add: no segments)
    add = _summer(comm)
    rank, ranks = comm.Get_rank(), comm.Get_size()
    n = _items(scene)
    lines = np.asarray(lines, dtype=np.float32)
    if lines.shape[0] != n:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"ivr.mpi.tomo: lines has {lines.shape[0]} rows on its first axis but the "
                    f"scene has {n} views or rays")
    if split == "slabs":
        weights = rank_weights(ctx, comm, shares)
        volume, history = ctx.tomo(scene, lines, _split=(1, rank, ranks, add, weights), **options)
        parts = comm.allgather(volume)  # a shared plane once, from the lower rank
        return np.concatenate([parts[0]] + [p[1:] for p in parts[1:]], axis=0), history
    if n < ranks:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"ivr.mpi.tomo: {ranks} ranks for {n} views or rays: at most one rank each")
    first, count = _mine(ctx, comm, n, shares)
    return ctx.tomo(scene_share(scene, first, count), lines[first:first + count],
                    _split=(0, rank, ranks, add, None), **options)


def reconstruct(ctx, scene, targets, comm=None, progress=None, split="views", nz=None, gather=True,
                shares=None, **options):
    """ctx.reconstruct with the ranks sharing out each batch's views (as `mpirun -np N ivr
    reconstruct`): every rank passes the whole scene and targets and the same options, draws the
    same batch, differentiates its share of its views, and the loss and gradients are summed over
    the ranks before every step, so every rank holds the same iterate (one process's bit for bit
    for densities with the TF fixed and deterministic gradients, else to the rounding of the sums).
    split="slabs" (as --split slabs): each rank holds one slab of z planes of the densities and
    marches every view through it (the densities, and the TF jointly), the slabs gathered
    at the end; split="segments" likewise, each ray's segments marched at once. Over slabs or
    segments each rank's planes follow rank_weights(ctx, comm, shares), and with nz=NZ,
    options["volume"] (the start) is this rank's planes ivr.mpi.slab(NZ, ctx=ctx, shares=shares)
    alone, and with gather=False "volume" comes back as this rank's planes. progress(entry) is called on every rank; returning False on any rank
    stops every rank after the same iteration. Cameras only; over views every batch needs at least
    one view per rank. Returns ctx.reconstruct's dict on every rank, "volume" whole (checkpoint:
    give each rank its own prefix — over slabs each rank's state is its own)."""
    comm = _comm(comm)
    scene = _scene_dict(scene)
    code = _check_split(split, "reconstruct")
    from mpi4py import MPI

    def agreed(entry):  # (collective: every rank calls it after every iteration)
        go = progress is None or progress(entry) is not False
        return comm.allreduce(0 if go else 1, op=MPI.SUM) == 0

    if split == "views":
        _whole_volume(nz, "reconstruct")
        views = _items(scene)
        batch = min(int(options.get("batch") or views), views)
        weights = _worker_weights(_counts(ctx, comm, batch, shares))
    else:
        weights = rank_weights(ctx, comm, shares)
    out = ctx.reconstruct(scene, targets, progress=agreed,
                          _workers=_slab_split(code, comm, nz, weights), **options)
    if split != "views" and "volume" in out and gather:
        parts = comm.allgather(out["volume"])  # a shared plane once, from the lower rank
        out["volume"] = np.concatenate([parts[0]] + [p[1:] for p in parts[1:]], axis=0)
    return out
