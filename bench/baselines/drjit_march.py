"""drjit_march.py — the ivr-bench emission–absorption march in Dr.Jit (LLVM or CUDA backend), for run.py.

How it is written (as a Dr.Jit user would; drjit.llvm.ad types on the CPU, drjit.cuda.ad on the
GPU):

* Devices: the array types (Float, UInt32, Array3f) are module globals that _use_backend() binds
  to drjit.llvm.ad ("cpu", the default at import) or drjit.cuda.ad ("gpu"); version() and
  prepare() choose. The code is the same for both. _Case puts the scene on the device (and waits
  for the copies) before the timed calls; every call ends with dr.eval of its outputs and
  dr.sync_thread() (both backends run kernels asynchronously: LLVM on its thread pool, CUDA on
  its stream) and returns them as device arrays (common.Deferred where the host needs to stack or
  reshape them): run.py copies them to the host after the clock stops.

* The volume is one flat differentiable Float; trilinear interpolation is 8 ``dr.gather``s.
* The ray loop is a symbolic ``dr.while_loop``: Dr.Jit compiles the whole march into one fused
  LLVM kernel with the loop state (i, T, C) in registers; rays stop independently (n, early
  termination).
* The transfer function is an unrolled comparison/``dr.select`` chain over its few points, with
  the point densities baked in as constants and [r, g, b, extinction] as width-1 variables. For
  the handful of points a TF has this is a few FMAs per sample in registers, while a gather by
  segment index would need the same comparisons to find the index plus 8 memory reads per
  sample (and, differentiated in reverse, scatter-adds of every sample into 4·points floats,
  i.e. maximal atomic contention).
* render: the loop as is.
* grad (reverse mode): T is carried multiplicatively from step to step, so this is not a "sum
  loop", the one kind Dr.Jit's documentation covers (docs/autodiff.rst, "Reverse-mode derivative
  of sum loops": ``max_iterations=-1``). Two ways are implemented; REVERSE selects one:
  - "replay" (default): the hand-written path-replay adjoint Mitsuba 3 uses for the same
    problem (prb/prbvolpath, "path replay backpropagation"): march once without AD, then replay
    the march with T and C detached and, per sample, ``dr.backward_from`` a local surrogate
    whose derivative is exactly that sample's contribution (see grad_replay). One primal plus
    one replay kernel, nothing stored per step.
  - "loop": Dr.Jit's own general reverse mode of a symbolic loop (Dr.Jit >= 1.5, drjit PR #491
    "Add general-purpose reverse-mode AD for symbolic loops"; ``dr.while_loop``'s
    ``max_iterations`` argument, here the largest sample count): a record pass stores the loop
    state of every iteration on the per-thread stack, a second pass runs the loop backwards.
    Without the hint Dr.Jit refuses ("reverse-mode differentiation of this loop requires a
    'max_iterations' hint"). Evaluated loops (mode="evaluated") also differentiate, but launch
    a kernel per step and keep every step's AD graph: O(steps × rays) memory.
  On the 128³, 256² benchmark case "replay" took ~1.0 s against ~1.4 s for "loop" (2 threads,
  interleaved runs), both with the Expand scatter mode below.
* tf_forward (forward mode): Dr.Jit's forward mode carries one tangent, so the loss is
  differentiated once per parameter (4 · points passes of one primal + tangent kernel each).
  The graph is traced once; every parameter is a grad-enabled opaque width-1 variable with an
  opaque seed of its own, so every pass launches the same cached kernel instead of compiling
  one per parameter. Dr.Jit has no multi-tangent (vmap-like) forward mode; widening the rays
  ×(4·points) to carry one-hot seeds would do the same arithmetic in one launch at ×(4·points)
  memory, so it gains nothing here.
* LLVM: float dr.minimum/dr.maximum (and so dr.clip) emit llvm.minimum/llvm.maximum, which the
  x86 backend of LLVM 15 (Debian 12's libLLVM-15, which Dr.Jit 1.5 accepts) cannot compile: the
  process aborts ("Cannot select: fminimum"). The clamps below are therefore selects. On CUDA
  they are kept as they are: a select of a compare is what a clamp compiles to there anyway
  (setp + selp instead of min/max), and the result is the same for every non-NaN input, so both
  backends compute the same march.
* CUDA: SCATTER_MODE Expand is LLVM-only; Dr.Jit's CUDA backend treats it as ReduceMode.Auto
  (warp-local pre-reduction or plain atomics). dr.exp is ex2.approx there (a few ulp), so GPU
  results differ from the CPU's in the last bits.
"""
from __future__ import annotations

import numpy as np

import drjit as dr  # an ImportError here is what run.py reports as "not installed"
from common import Deferred, DeviceUnavailable
from drjit.llvm.ad import Array3f, Float, UInt32  # rebound by _use_backend("gpu")

BACKEND = dr.JitBackend.LLVM  # the backend the array types above belong to

# "replay": hand-written path-replay adjoint (Mitsuba's PRB pattern, default);
# "loop": Dr.Jit's built-in reverse mode of the symbolic loop (max_iterations hint).
REVERSE = "replay"

# How the reverse-mode adjoint of the corner gathers (a scatter-add into the volume's gradient)
# is compiled. Every sample adds into 8 voxels that neighbouring rays/samples share: as atomics
# (Direct) that contends badly on the CPU; Expand gives each worker thread its own copy of the
# gradient array (threads × 4 bytes × voxels) and adds without atomics, then sums the copies.
# Dr.Jit picks Expand by itself only for arrays up to dr.expand_threshold() (1M entries).
SCATTER_MODE = dr.ReduceMode.Expand


def _use_backend(device: str) -> None:
    """Binds Float/UInt32/Array3f to drjit.llvm.ad ("cpu") or drjit.cuda.ad ("gpu")."""
    global Array3f, Float, UInt32, BACKEND
    if device == "gpu":
        if not dr.has_backend(dr.JitBackend.CUDA):
            raise DeviceUnavailable(f"drjit {dr.__version__}'s CUDA backend is unavailable "
                                    "(no libcuda/driver found, or no CUDA device)")
        try:
            import drjit.cuda.ad as types
        except ImportError as e:
            raise DeviceUnavailable(f"drjit.cuda.ad cannot be imported ({e})") from e
        BACKEND = dr.JitBackend.CUDA
    else:
        import drjit.llvm.ad as types

        BACKEND = dr.JitBackend.LLVM
    Array3f, Float, UInt32 = types.Array3f, types.Float, types.UInt32


def version(threads: int, device: str = "cpu") -> str:
    """Checks Dr.Jit's backend for `device` ("cpu": LLVM with `threads` threads, 0: its own
    choice; "gpu": CUDA, `threads` unused) and selects it; ImportError when the CPU backend is
    unusable, DeviceUnavailable when the CUDA one is."""
    if not hasattr(dr, "while_loop"):
        raise ImportError(f"drjit {dr.__version__} is too old (dr.while_loop needs >= 1.0)")
    if device == "gpu":
        _use_backend(device)
        return f"drjit {dr.__version__} (CUDA backend, {device_name(device)})"
    if not dr.has_backend(dr.JitBackend.LLVM):
        # No libLLVM found at run time: the LLVM backend, the only CPU backend, is unusable.
        raise ImportError("drjit's LLVM backend is unavailable (libLLVM not found)")
    _use_backend(device)
    if threads > 0:
        dr.set_thread_count(threads)
    return f"drjit {dr.__version__} (LLVM backend, {dr.thread_count()} threads)"


def _cuda_device_name() -> str:
    """The name of CUDA device 0 (the one Dr.Jit uses unless told otherwise), from the driver API;
    Dr.Jit itself exposes only the compute capability."""
    import ctypes

    cuda = ctypes.CDLL("libcuda.so.1")
    dev = ctypes.c_int()
    name = ctypes.create_string_buffer(256)
    if cuda.cuInit(0) or cuda.cuDeviceGet(ctypes.byref(dev), 0) or \
            cuda.cuDeviceGetName(name, len(name), dev):
        raise OSError("cuDeviceGetName failed")
    return name.value.decode(errors="replace")


def device_name(device: str = "cpu") -> str:
    """The backend and what it runs on: "CUDA: NVIDIA H100 ... (sm_90)", "LLVM 15.0.6"."""
    if device == "gpu":
        cc = dr.detail.cuda_compute_capability()
        try:
            name = _cuda_device_name()
        except (OSError, AttributeError):
            name = "CUDA device 0"
        return f"CUDA: {name} (sm_{cc})"
    return "LLVM " + ".".join(str(v) for v in dr.detail.llvm_version())


def device_memory(reset: bool = False):
    """Dr.Jit's allocator high-water mark on the backend in use (its cache included). Dr.Jit cannot
    reset it nor tell the bytes in use, so it covers the whole process (setup and first call)."""
    return {"in_use": None, "peak": int(dr.detail.malloc_watermark(BACKEND)), "scope": "process"}


class _Case:
    """The scene moved to Dr.Jit once (outside the timed calls)."""

    def __init__(self, scene):
        r = scene.rays
        self.nz, self.ny, self.nx = scene.volume.shape
        self.views, self.H, self.W = scene.views, scene.height, scene.width
        self.R = len(r.n)
        self.u0 = Array3f(*(Float(np.ascontiguousarray(r.u0[:, a])) for a in range(3)))
        self.du = Array3f(*(Float(np.ascontiguousarray(r.du[:, a])) for a in range(3)))
        self.t0 = Float(r.t0)
        self.dt = Float(r.dt)
        self.n = UInt32(r.n.astype(np.uint32))
        self.volume = Float(np.ascontiguousarray(scene.volume).ravel())
        t = scene.target.reshape(-1, 4)
        self.target = [Float(np.ascontiguousarray(t[:, c])) for c in range(4)]
        self.tf_density = [float(d) for d in scene.tf[:, 0]]
        self.tf_values = scene.tf[:, 1:5].astype(np.float32)  # (points, 4): r, g, b, extinction
        self.background = [float(b) for b in scene.background]
        self.min_t = float(scene.min_transmittance)
        self.max_samples = max(1, scene.max_samples)
        dr.eval(self.u0, self.du, self.t0, self.dt, self.n, self.volume, self.target)
        dr.sync_thread()  # the copies to the device are done before the first call

    # -- the march ------------------------------------------------------------------------------

    def density(self, vol: Float, u: Array3f) -> Float:
        """Trilinear sample at voxel-index coordinates u (clamped per axis to the volume)."""
        i0, i1, f = [], [], []
        for a, size in enumerate((self.nx, self.ny, self.nz)):
            # Clamp by selects, not dr.clip (see "LLVM" above: LLVM 15 aborts on it).
            c = dr.select(u[a] > 0.0, u[a], 0.0)
            c = dr.select(c < float(size - 1), c, float(size - 1))
            c0 = dr.floor(c)
            f.append(c - c0)
            lo = UInt32(c0)
            i0.append(lo)
            i1.append(dr.minimum(lo + 1, size - 1))  # the +1 neighbour stays inside at the edge
        nx, ny = self.nx, self.ny

        def at(z, y, x):
            return dr.gather(Float, vol, (z * ny + y) * nx + x, mode=SCATTER_MODE)

        x0, x1 = i0[0], i1[0]
        rows = []
        for z in (i0[2], i1[2]):
            for y in (i0[1], i1[1]):
                rows.append(dr.lerp(at(z, y, x0), at(z, y, x1), f[0]))
        return dr.lerp(dr.lerp(rows[0], rows[1], f[1]), dr.lerp(rows[2], rows[3], f[1]), f[2])

    def classify(self, d: Float, tf) -> list:
        """Piecewise-linear TF as an unrolled select chain: [r, g, b, extinction] at density d."""
        dens = self.tf_density
        out = list(tf[0])  # d <= d_0 (and a single point): the first point
        for k in range(len(dens) - 1):
            lo, hi = dens[k], dens[k + 1]
            if not hi > lo:  # an empty segment is never selected (and must not divide by 0)
                continue
            inside = (d >= lo) & (d < hi)
            if k == 0:
                inside &= d > lo  # d == d_0 takes the "else" branch: first point, zero slope
            w = (d - lo) / (hi - lo)
            out = [dr.select(inside, dr.lerp(a, b, w), o) for a, b, o in zip(tf[k], tf[k + 1], out)]
        last = d >= dens[-1]  # at/after the last point: its values, zero derivative in d
        return [dr.select(last, v, o) for v, o in zip(tf[-1], out)]

    def step(self, vol, tf, i):
        """Sample i of every ray: (colour [3], tau)."""
        t = self.t0 + (Float(i) + 0.5) * self.dt
        u = self.u0 + t * self.du
        r, g, b, sigma = self.classify(self.density(vol, u), tf)
        return (r, g, b), sigma * self.dt

    def active(self, i, T):
        return (i < self.n) & (T >= self.min_t)  # a sample is taken only while T >= min_T

    def march(self, vol, tf, max_iterations=None):
        """C (rgb) and T of every ray."""

        def body(i, T, C):
            col, tau = self.step(vol, tf, i)
            a = dr.exp(-tau)
            C = C + (T * (1.0 - a)) * Array3f(*col)
            return i + 1, T * a, C

        _, T, C = dr.while_loop(
            state=(UInt32(0), dr.full(Float, 1.0, self.R), dr.zeros(Array3f, self.R)),
            cond=lambda i, T, C: self.active(i, T),
            body=body,
            labels=("i", "T", "C"),
            label="ivr_march",
            mode="symbolic",
            max_iterations=max_iterations,
        )
        return T, C

    def pixels(self, T, C):
        return [C[c] + T * self.background[c] for c in range(3)] + [1.0 - T]

    def loss(self, px) -> Float:
        # One reduction over a per-ray sum: a reduction evaluates its input, and in forward mode
        # each dr.sum would launch its own (primal + tangent) march kernel.
        err = dr.square(px[0] - self.target[0])
        for c in range(1, 4):
            err += dr.square(px[c] - self.target[c])
        return dr.sum(err) / float(4 * self.R)

    def tf_constants(self):
        return [[Float(float(v)) for v in row] for row in self.tf_values]

    # -- outputs: computed on the device in the call, copied to the host after it ---------------

    @staticmethod
    def finish(*values) -> None:
        """The end of every call: evaluate the outputs and wait until the device is done."""
        dr.eval(*values)
        dr.sync_thread()

    def image(self, px) -> Deferred:
        def fetch():
            img = np.stack([np.asarray(p, dtype=np.float32) for p in px], axis=-1)
            return img.reshape(self.views, self.H, self.W, 4)

        return Deferred(fetch)

    def grad_array(self, grad) -> Deferred:
        shape = (self.nz, self.ny, self.nx)
        return Deferred(lambda: np.asarray(grad, dtype=np.float32).reshape(shape))

    @staticmethod
    def scalar(value) -> Deferred:
        return Deferred(lambda: float(value[0]))

    # -- tasks ----------------------------------------------------------------------------------

    def render(self):
        T, C = self.march(self.volume, self.tf_constants())
        px = self.pixels(T, C)
        self.finish(px)
        return {"image": self.image(px)}

    def grad_loop(self):
        """Dr.Jit's own reverse mode of the symbolic loop: record + reverse replay on the stack."""
        vol = Float(self.volume)  # a fresh AD leaf that shares the storage; grads do not pile up
        dr.enable_grad(vol)
        T, C = self.march(vol, self.tf_constants(), max_iterations=self.max_samples)
        loss = self.loss(self.pixels(T, C))
        dr.backward(loss)
        grad = dr.grad(vol)
        self.finish(loss, grad)
        return {"loss": self.scalar(loss), "grad": self.grad_array(grad)}

    def grad_replay(self):
        """Path-replay adjoint: a primal march without AD, then a replay that backpropagates
        per sample. For the sample i with T_i (before it), a_i = exp(-tau_i), colour c_i:
          dC/dc_i   = T_i (1 - a_i)
          dC/dtau_i = T_i a_i c_i - (C - C_{<=i})    (every later sample is scaled by a_i)
          dT/dtau_i = -T
        so with dL/dC = δC and dL/dT = δT the surrogate
          s_i = δC · T_i (1 - a_i) c_i - (δC · (C - C_{<=i}) + δT T) tau_i,
        with T_i, C_{<=i}, C, T held constant, has exactly sample i's derivative; backpropagating
        it into the volume inside the loop accumulates the gradient without storing anything."""
        tf = self.tf_constants()
        T, C = self.march(self.volume, tf)
        px = self.pixels(T, C)
        dr.eval(T, C, px)  # T and C too: the replay needs them, else the march would run again
        loss = self.loss(px)
        scale = 2.0 / float(4 * self.R)  # d mean((p - t)^2) / dp
        dC = Array3f(*((px[c] - self.target[c]) * scale for c in range(3)))
        dA = (px[3] - self.target[3]) * scale
        dT = dC[0] * self.background[0] + dC[1] * self.background[1] + dC[2] * self.background[2] - dA
        dTT = dT * T  # dL/dT · T: every tau_i's share through the final transmittance
        dr.eval(dC, dTT)

        vol = Float(self.volume)
        dr.enable_grad(vol)

        def body(i, Ti, Ci):
            with dr.resume_grad():
                col, tau = self.step(vol, tf, i)
                a = dr.exp(-tau)
                contrib = (Ti * (1.0 - a)) * Array3f(*col)
                a0, contrib0 = dr.detach(a), dr.detach(contrib)
                after = Ci + contrib0  # C_{<=i}
                s = dr.dot(dC, contrib) - (dr.dot(dC, C - after) + dTT) * tau
                dr.backward_from(s)
            return i + 1, Ti * a0, after

        dr.while_loop(
            state=(UInt32(0), dr.full(Float, 1.0, self.R), dr.zeros(Array3f, self.R)),
            cond=lambda i, Ti, Ci: self.active(i, Ti),
            body=body,
            labels=("i", "T", "C"),
            label="ivr_march_adjoint",
            mode="symbolic",
        )
        grad = dr.grad(vol)  # evaluating it runs the replay kernel (its scatter-adds)
        self.finish(loss, grad)
        return {"loss": self.scalar(loss), "grad": self.grad_array(grad)}

    def tf_forward(self):
        points = len(self.tf_values)
        # Opaque (not literal) parameters and seeds: every pass reuses one compiled kernel.
        tf = [[dr.opaque(Float, float(v)) for v in row] for row in self.tf_values]
        flat = [p for row in tf for p in row]
        dr.enable_grad(flat)
        T, C = self.march(self.volume, tf)
        loss = self.loss(self.pixels(T, C))
        dr.eval(loss)
        grads = []  # one width-1 device array per parameter, read on the host after the call
        for k in range(len(flat)):
            # A distinct opaque seed per parameter: the kernel then has the same inputs in the
            # same places for every k (a shared "zero" variable would change its structure).
            for j, p in enumerate(flat):
                dr.set_grad(p, dr.opaque(Float, 1.0 if j == k else 0.0))
            dr.clear_grad(loss)  # the output's tangent is not cleared by the traversal
            # Keep the traced graph (edges) for the next parameter; clear propagated values.
            grads.append(dr.forward_to(loss, flags=dr.ADFlag.ClearVertices))
        dr.disable_grad(flat)
        self.finish(loss, grads)

        def fetch():
            values = np.array([float(g[0]) for g in grads], np.float64)
            return values.reshape(points, 4).astype(np.float32)

        return {"loss": self.scalar(loss), "tf_grad": Deferred(fetch)}


def prepare(task: str, scene, device: str = "cpu"):
    """Returns call() for `task` on `scene`, on Dr.Jit's backend for `device`; the scene is on the
    device before the call is timed."""
    _use_backend(device)
    case = _Case(scene)
    if task == "render":
        return case.render
    if task == "grad":
        return case.grad_replay if REVERSE == "replay" else case.grad_loop
    if task == "tf_forward":
        return case.tf_forward
    raise ValueError(f"drjit_march: unknown task {task!r}")
