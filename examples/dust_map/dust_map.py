#!/usr/bin/env python3
"""dust_map.py — a 3D dust map from stellar sightlines (issue 23): ivr's ray lists and tomography
solver recover a synthetic dust cloud from the extinction towards many stars.

    python3 examples/dust_map/dust_map.py [--size 96] [--stars 100000] [--sigma MAG]
                                          [--solver sirt] [--iterations 100] [--smooth 10]
                                          [--tv LAMBDA] [--out DIR] [--quick]

The truth: a 1 kpc cube (ivr's box [-0.5, 0.5]^3, so 1 box unit = 1 kpc) around the observer at
its centre, on an N^3 grid (N = 96: 10.4 pc voxels), holding extinction per unit length in
mag/kpc: a log-normal field (a Gaussian random field with a Kolmogorov spectrum P(k) ~ k^-11/3,
outer scale 1 kpc, smoothed by a 20 pc Gaussian, exponentiated; mean 1 mag/kpc) plus six compact
dense clouds (Gaussian blobs of 15-40 pc, 15-40 mag/kpc at their centres). Stars lie uniformly in
the cube; each star's extinction is ivr's exact line integral of the truth from the observer to
the star (a ray list of [0, 0, 0, star x, y, z] rows) plus Gaussian noise of sigma. ivr's solver
reconstructs the map on the same grid (default: SIRT with x >= 0, stopped by the discrepancy
principle once the residual reaches the noise); a Gaussian filter of --smooth pc then stands in
for a smoothness prior. Both maps are compared with the truth, overall and in 8 distance shells of
108 pc, next to a trivial map (one constant fitted to the data) and the truth blurred by 20 pc.

Prints the timings and errors; writes slices.png, error_vs_distance.png, summary.png and
errors.json into --out (default: a new temporary folder) once everything is computed; exits 1
unless the relative error of ivr's map is below both --max-error (0.5) and the constant map's.
--quick (32^3, 20000 stars) takes seconds: the CTest example_dust_map."""
import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

import ivr

KPC = 1000.0  # pc per box unit
# The dense clouds: centre (pc), Gaussian sigma (pc), extinction at the centre (mag/kpc).
CLOUDS = [((150, 60, 0), 20, 30), ((-250, 200, -20), 30, 20), ((50, -320, 10), 25, 25),
          ((-380, 20, 5), 15, 40), ((-120, -100, -300), 40, 15), ((300, 300, 350), 30, 20)]
SHELLS = 8  # distance shells from 0 to the cube's corner, sqrt(3)/2 kpc
BLUR_PC = 20.0  # the reference map: the truth blurred by a Gaussian of this sigma
# The maps compared, by their keys in errors.json.
IVR_MAP, SMOOTHED_MAP, CONSTANT_MAP = "ivr map", "smoothed map", "constant map"
BLURRED_TRUTH = f"truth blurred by {BLUR_PC:.0f} pc"


def voxel_centres(n):
    """Voxel-centre coordinates (box units = kpc) of an n^3 grid on [-0.5, 0.5]^3."""
    return -0.5 + (np.arange(n) + 0.5) / n


def dust_truth(n, rng, smoothing_pc=20.0, sigma_ln=1.0, mean=1.0):
    """Extinction per unit length (mag/kpc), float32 (Z, Y, X): log-normal field plus clouds."""
    k = np.fft.fftfreq(n, d=1.0 / n)  # cycles per kpc
    kz, ky, kx = np.meshgrid(k, k, np.fft.rfftfreq(n, d=1.0 / n), indexing="ij")
    kk = np.sqrt(kx * kx + ky * ky + kz * kz)
    # sqrt of P(k) = (k^2 + k0^2)^(-11/6) (k0 = 1/kpc) times a Gaussian smoothing's transfer.
    amplitude = (kk * kk + 1.0) ** (-11.0 / 12.0) * np.exp(
        -0.5 * (2 * np.pi * kk * smoothing_pc / KPC) ** 2)
    g = np.fft.irfftn(np.fft.rfftn(rng.standard_normal((n, n, n))) * amplitude, s=(n, n, n))
    g = (g - g.mean()) / g.std()
    field = np.exp(sigma_ln * g)
    field *= mean / field.mean()
    c = voxel_centres(n)
    z, y, x = np.meshgrid(c, c, c, indexing="ij", sparse=True)
    for (cx, cy, cz), s, peak in CLOUDS:
        r2 = (x - cx / KPC) ** 2 + (y - cy / KPC) ** 2 + (z - cz / KPC) ** 2
        field = field + peak * np.exp(-r2 / (2 * (s / KPC) ** 2))
    return field.astype(np.float32)


def distance_grid(n):
    """Each voxel centre's distance from the observer at the origin (kpc), (Z, Y, X)."""
    c = voxel_centres(n)
    z, y, x = np.meshgrid(c, c, c, indexing="ij", sparse=True)
    return np.sqrt(x * x + y * y + z * z)


def relative_errors(estimate, truth, distance, edges):
    """(overall, [per shell]) relative L2 errors |estimate - truth| / |truth|."""
    d = estimate - truth
    overall = float(np.linalg.norm(d) / np.linalg.norm(truth))
    shells = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (distance >= lo) & (distance < hi)
        shells.append(float(np.linalg.norm(d[m]) / np.linalg.norm(truth[m])))
    return overall, shells


def gaussian_filter(volume, sigma_voxels):
    """`volume` filtered by a Gaussian of sigma_voxels along each axis (cut at 3 sigma),
    normalised at the box's faces: each voxel the weighted mean of the voxels inside the box."""
    if sigma_voxels <= 0:
        return volume
    r = max(int(np.ceil(3 * sigma_voxels)), 1)
    taps = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma_voxels) ** 2)
    out, weight = volume.astype(np.float64), np.ones(volume.shape)
    for axis in range(3):
        pad = [(0, 0)] * 3
        pad[axis] = (r, r)
        padded, ones = np.pad(out, pad), np.pad(weight, pad)
        n = volume.shape[axis]
        out = sum(t * np.take(padded, range(i, i + n), axis=axis) for i, t in enumerate(taps))
        weight = sum(t * np.take(ones, range(i, i + n), axis=axis) for i, t in enumerate(taps))
    return (out / weight).astype(np.float32)


def write_figures(out, truth, maps, edges, errors, label, stars):
    """slices.png, error_vs_distance.png and summary.png into `out`; maps: {title: volume},
    the last one the map whose error is shown."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    n = truth.shape[0]
    half = 0.5 * KPC
    extent = [-half, half, -half, half]
    vmin, vmax = 0.05, float(truth.max())
    final = list(maps.values())[-1]
    err_lim = float(np.percentile(np.abs(final - truth), 99.9))
    centres = 0.5 * (edges[:-1] + edges[1:]) * KPC
    offset = voxel_centres(n)[n // 2] * KPC
    # The planes through the observer: z = 0 (x right, y up) and y = 0 (x right, z up).
    planes = [("z", lambda v: v[n // 2], "y (pc)"), ("y", lambda v: v[:, n // 2, :], "z (pc)")]

    def slice_row(axes, plane):
        axis, cut, ylabel = plane
        log = dict(norm=LogNorm(vmin, vmax), cmap="magma")
        panels = [(cut(truth), "truth", log)]
        panels += [(np.maximum(cut(v), vmin), title, log) for title, v in maps.items()]
        panels.append((cut(final) - cut(truth), f"{list(maps)[-1]} − truth",
                       dict(vmin=-err_lim, vmax=err_lim, cmap="RdBu_r")))
        for ax, (image, title, style) in zip(axes, panels):
            im = ax.imshow(image, origin="lower", extent=extent, interpolation="nearest", **style)
            ax.plot(0, 0, marker="*", color="cyan", markersize=9, markeredgecolor="k")
            ax.set_title(f"{title}\n{axis} = {offset:+.0f} pc slice", fontsize=9)
            ax.set_xlabel("x (pc)")
            ax.set_ylabel(ylabel)
            plt.colorbar(im, ax=ax, fraction=0.046, pad=0.04).set_label("extinction (mag/kpc)")

    def error_plot(ax):
        styles = ["o-", "D-", "s--", "^:"]
        for (name, e), style in zip(errors.items(), styles):
            ax.plot(centres, e["shells"], style, label=f"{name} (overall {e['overall']:.3f})")
        ax.axvline(half, color="grey", lw=0.8)
        ax.text(half, 0.98, " cube faces; beyond:\n its corners only", fontsize=8, color="grey",
                va="top", transform=ax.get_xaxis_transform())
        ax.set_xlabel("distance from the observer (pc), shell centre")
        ax.set_ylabel("relative L2 error in the shell")
        ax.set_title(f"error against distance ({label}; {stars} stars)", fontsize=9)
        ax.set_ylim(0, max(1.0, 1.1 * max(max(e["shells"]) for e in errors.values())))
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower left")

    columns = len(maps) + 2
    paths = {}
    fig, axes = plt.subplots(2, columns, figsize=(5 * columns, 9.2))
    for row, plane in zip(axes, planes):
        slice_row(row, plane)
    fig.tight_layout(w_pad=3)
    paths["slices"] = os.path.join(out, "slices.png")
    fig.savefig(paths["slices"], dpi=80)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4.5))
    error_plot(ax)
    fig.tight_layout()
    paths["error_vs_distance"] = os.path.join(out, "error_vs_distance.png")
    fig.savefig(paths["error_vs_distance"], dpi=100)
    plt.close(fig)

    # The summary: the z = 0 slices, then the error slice and the error against distance.
    fig = plt.figure(figsize=(5 * (columns - 1), 9.2))
    grid = fig.add_gridspec(2, 2 * (columns - 1))
    top = [fig.add_subplot(grid[0, 2 * i:2 * i + 2]) for i in range(columns - 1)]
    error_slice = fig.add_subplot(grid[1, 0:2])
    slice_row(top + [error_slice], planes[0])
    error_plot(fig.add_subplot(grid[1, 2:]))
    fig.tight_layout(w_pad=3)
    paths["summary"] = os.path.join(out, "summary.png")
    fig.savefig(paths["summary"], dpi=70)
    plt.close(fig)
    return paths


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=None, help="voxels per axis (default 96)")
    parser.add_argument("--stars", type=int, default=None, help="sightlines (default 100000)")
    parser.add_argument("--sigma", type=float, default=None,
                        help="noise of each star's extinction, mag (default: 2%% of the median "
                             "true extinction + 0.01 mag)")
    parser.add_argument("--solver", choices=("sirt", "cgls", "lsqr"), default="sirt")
    parser.add_argument("--iterations", type=int, default=None,
                        help="most iterations (default 100; --quick 60)")
    parser.add_argument("--relaxation", type=float, default=1.9, help="SIRT's omega in (0, 2)")
    parser.add_argument("--discrepancy", type=float, default=1.0,
                        help="stop once |p - N x| <= this * sigma * sqrt(stars) (the discrepancy "
                             "principle; 0: run every iteration)")
    parser.add_argument("--nonneg", action=argparse.BooleanOptionalAction, default=None,
                        help="x >= 0 after every iteration (default: with sirt only; ivr's CGLS "
                             "and LSQR restart after every such projection and crawl); the "
                             "map is clipped at 0 either way")
    parser.add_argument("--tv", type=float, default=0.0,
                        help="ivr's smoothed-TV weight lambda (with cgls or lsqr: see README)")
    parser.add_argument("--tv-epsilon", type=float, default=0.1)
    parser.add_argument("--smooth", type=float, default=10.0,
                        help="sigma (pc) of the Gaussian filter applied to ivr's map; 0: none")
    parser.add_argument("--seed", type=int, default=23)
    parser.add_argument("--max-error", type=float, default=0.5,
                        help="exit 1 unless ivr's map's relative error is below this")
    parser.add_argument("--out", default=None, help="folder for the PNGs and errors.json "
                                                    "(default: a new temporary folder)")
    parser.add_argument("--quick", action="store_true",
                        help="32^3 grid, 20000 stars, at most 60 iterations (seconds)")
    args = parser.parse_args(argv)
    n = args.size or (32 if args.quick else 96)
    stars = args.stars or (20000 if args.quick else 100000)
    iterations = args.iterations or (60 if args.quick else 100)
    nonneg = args.solver == "sirt" if args.nonneg is None else args.nonneg
    if n < 8 or stars < 1 or iterations < 1:
        parser.error("--size must be >= 8, --stars and --iterations >= 1")

    start = time.perf_counter()
    truth_rng, star_rng, noise_rng = (np.random.default_rng(s) for s in
                                      np.random.SeedSequence(args.seed).spawn(3))
    truth = dust_truth(n, truth_rng)
    distance = distance_grid(n)
    # Uniform in the cube (a volume-complete sample); the first k stars of a run with more stars
    # are the same k stars, with the same noise, so runs with different --stars compare cleanly.
    positions = star_rng.uniform(-0.5, 0.5, size=(stars, 3))
    rays = np.hstack([np.zeros((stars, 3)), positions])  # observer -> star, [start xyz, end xyz]
    scene = {"box": {"min": [-0.5] * 3, "max": [0.5] * 3},
             "volume": {"synthetic": "zeros", "dims": [n, n, n]}, "rays": rays}
    t_truth = time.perf_counter() - start

    with ivr.Context() as ctx:
        print(f"ivr on {ctx.device}: {n}³ grid ({KPC / n:.1f} pc voxels) in a 1 kpc cube, "
              f"{stars} stars, observer at the centre")
        t0 = time.perf_counter()
        exact = ctx.project(scene, volume=truth)[:, 0].astype(np.float64)
        t_project = time.perf_counter() - t0
        median = float(np.median(exact))
        sigma = args.sigma if args.sigma is not None else 0.02 * median + 0.01
        lines = exact + noise_rng.normal(0.0, sigma, size=stars)
        print(f"truth: mean {truth.mean():.3f} mag/kpc, max {truth.max():.1f} mag/kpc; star "
              f"extinctions: median {median:.3f} mag, 99th percentile "
              f"{np.percentile(exact, 99):.2f} mag; noise sigma {sigma:.4f} mag")
        # The discrepancy principle: a residual below the noise would be fitting the noise.
        noise_level = sigma * np.sqrt(stars) / np.linalg.norm(lines)
        tolerance = args.discrepancy * noise_level
        regulariser = f", TV λ {args.tv:g} (ε {args.tv_epsilon:g})" if args.tv > 0 else ""
        label = f"{args.solver.upper()}{', x ≥ 0' if nonneg else ''}{regulariser}"
        print(f"reconstructing: {label}, at most {iterations} iterations, stop at residual "
              f"|p - N x| / |p| <= {tolerance:.4f} (noise level {noise_level:.4f})")
        info = {}
        every = max(iterations // 10, 1)

        def progress(entry):
            if entry["iteration"] % every == 0:
                print(f"  iteration {entry['iteration']:4d}  residual {entry['residual']:.4f}  "
                      f"{entry['seconds']:6.1f} s", flush=True)

        t0 = time.perf_counter()
        volume, history = ctx.tomo(
            scene, lines.astype(np.float32), solver=args.solver, iterations=iterations,
            nonneg=nonneg, tv=args.tv, tv_epsilon=args.tv_epsilon, tolerance=tolerance,
            relaxation=args.relaxation if args.solver == "sirt" else None, grid=(n, n, n),
            progress=progress, info=info)
        t_solve = time.perf_counter() - t0
    if not np.all(np.isfinite(volume)):
        print("FAIL: ivr's map is not finite", flush=True)
        return 1
    volume = np.maximum(volume, 0.0)  # densities are >= 0 (a no-op after x >= 0)
    print(f"  stopped after {len(history)} iterations ({info['stop_reason']}), residual "
          f"{history[-1]['residual']:.4f}; {t_solve:.1f} s (setup {info['setup_seconds']:.1f} s)")

    t0 = time.perf_counter()
    maps = {f"ivr's map ({label})": volume}
    if args.smooth > 0:
        maps[f"ivr's map, {args.smooth:g} pc filter"] = gaussian_filter(volume,
                                                                        args.smooth / KPC * n)
    # The trivial map: one constant c fitted to the data, min |c L - p| (L the path lengths).
    path = np.linalg.norm(positions, axis=1)
    constant = float(lines @ path / (path @ path))
    edges = np.linspace(0.0, np.sqrt(3) / 2, SHELLS + 1)
    estimates = {IVR_MAP: volume}
    if args.smooth > 0:
        estimates[SMOOTHED_MAP] = list(maps.values())[-1]
    estimates[CONSTANT_MAP] = np.full_like(truth, constant)
    estimates[BLURRED_TRUTH] = gaussian_filter(truth, BLUR_PC / KPC * n)
    errors = {}
    for name, estimate in estimates.items():
        overall, shells = relative_errors(estimate, truth, distance, edges)
        errors[name] = {"overall": overall, "shells": shells}
    t_errors = time.perf_counter() - t0

    smoothing = f"; smoothed map: {args.smooth:g} pc filter" if args.smooth > 0 else ""
    print(f"\nrelative L2 error |map - truth| / |truth| per distance shell (constant map: "
          f"{constant:.3f} mag/kpc{smoothing}):")
    print(f"  {'shell (pc)':>11} {'voxels':>7} {'stars':>7} " +
          " ".join(f"{name:>{max(len(name), 7)}}" for name in errors))
    for i, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        voxels = int(np.count_nonzero((distance >= lo) & (distance < hi)))
        count = int(np.count_nonzero((path >= lo) & (path < hi)))
        print(f"  {lo * KPC:4.0f}-{hi * KPC:<4.0f}   {voxels:7d} {count:7d} " +
              " ".join(f"{e['shells'][i]:{max(len(name), 7)}.3f}" for name, e in errors.items()))
    print(f"  {'all':>11} {n ** 3:7d} {stars:7d} " +
          " ".join(f"{e['overall']:{max(len(name), 7)}.3f}" for name, e in errors.items()))

    out = args.out or tempfile.mkdtemp(prefix="dust_map-")
    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    paths = write_figures(out, truth, maps, edges, errors, label, stars)
    t_figures = time.perf_counter() - t0
    total = time.perf_counter() - start
    record = {"size": n, "stars": stars, "sigma_mag": sigma, "solver": args.solver,
              "nonneg": nonneg, "tv": args.tv, "tv_epsilon": args.tv_epsilon,
              "relaxation": args.relaxation, "tolerance": tolerance, "smooth_pc": args.smooth,
              "iterations": len(history), "stop_reason": info["stop_reason"],
              "residual": history[-1]["residual"], "constant_map": constant,
              "shell_edges_pc": list(edges * KPC), "errors": errors,
              "seconds": {"truth": t_truth, "project": t_project, "solve": t_solve,
                          "errors": t_errors, "figures": t_figures, "total": total}}
    paths["errors"] = os.path.join(out, "errors.json")
    with open(paths["errors"], "w") as f:
        json.dump(record, f, indent=1)
    print(f"\ntimes: truth {t_truth:.1f} s, projection {t_project:.2f} s, solver {t_solve:.1f} s, "
          f"filter and errors {t_errors:.1f} s, figures {t_figures:.1f} s; total {total:.1f} s")
    print("wrote " + ", ".join(paths.values()))

    error, trivial = errors[IVR_MAP]["overall"], errors[CONSTANT_MAP]["overall"]
    if not (error < args.max_error and error < trivial):
        print(f"FAIL: the relative error of ivr's map, {error:.3f}, is not below both "
              f"{args.max_error} and the constant map's {trivial:.3f}", flush=True)
        return 1
    print(f"ivr's map: relative error {error:.3f} < {args.max_error} and < the constant map's "
          f"{trivial:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
