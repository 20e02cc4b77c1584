"""ivr.torch — ivr's renderer and absorption projector as PyTorch autograd functions over one
device-resident ivr.Session each.

    import torch, ivr.torch
    renderer = ivr.torch.Renderer(scene)            # a scene dict (docs/design.md); one Session
    density = torch.full((24, 24, 24), 0.3, requires_grad=True)
    image = renderer(density)                       # (views, H, W, C), differentiable
    ((image - target) ** 2).mean().backward()       # density.grad

Renderer(density=None, tf=None, background=None, camera=None) takes each as a tensor (or leaves
it as the session has it): density (Z, Y, X) >= 0; tf in the TF gradient's layout (rows x 4
[r, g, b, extinction] for piecewise_linear and table, rows x 6 [.., mean, width] for gaussian,
(2,) [extinction_scale, color_scale] for identity); background (3,) RGB or (1,) I_in for
absorption; camera (views, 7) [eye xyz, target xyz, fov_y] of the scene's listed cameras. The
backward of every tensor that requires a gradient is one call of the session's gradient with the
dot loss (dL/dimage as the weights: the vector-Jacobian product), in the mode ivr's planner
chooses from the parameter count (forward mode for few parameters — TF, background, camera —
the adjoint for voxels) unless `mode` says otherwise.

project(projector, volume) and backproject(projector, lines) are the exact line integrals
N v of an absorption scene's rays and their transpose N^T p, each the other's backward.

Data path: where the device's memory is the host's (CPUs through PoCL: `module.zero_copy`), the
returned images, gradients and projections are tensors over the device arrays' own memory
(DeviceArray.view: mapped, not copied) and the incoming dL/dimage and projected volumes are read
by the kernels from the tensors' memory (DeviceArray.wrap); only the densities, TF, background
and cameras are copied once into the session, which owns them (it checks the densities and
builds its empty-space grid from its copy). Elsewhere each array is copied once each way. Tensors
on other torch devices pass through host memory. The session keeps what the last call set; a
backward after another forward of the same Renderer sets its own forward's tensors again.
"""
import json

import numpy as np
import torch

from . import Context, Error, Session, DeviceArray

__all__ = ["Renderer", "Projector", "project", "backproject"]

_TF_COLUMNS = {"piecewise_linear": 4, "table": 4, "gaussian": 6}


def _host(tensor, dtype, what):
    """`tensor` as contiguous host numpy memory of `dtype` (a view for a CPU tensor of that
    dtype: no copy)."""
    if not isinstance(tensor, torch.Tensor):
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"{what} must be a torch.Tensor, got {type(tensor).__name__}")
    if tensor.is_complex() or not tensor.is_floating_point():
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"{what} must be a floating-point tensor, got {tensor.dtype}")
    return np.ascontiguousarray(tensor.detach().cpu().numpy(), dtype=dtype)


def _tf_with(tf, values):
    """The TF dict `tf` with its differentiable parameters replaced by `values` (numpy, the TF
    gradient's layout)."""
    kind = tf.get("type")
    out = json.loads(json.dumps(tf))
    if kind == "identity":
        v = values.reshape(-1)
        if v.size != 2:
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        f"tf: an identity TF has 2 parameters (extinction_scale, color_scale), "
                        f"got shape {values.shape}")
        out["extinction_scale"], out["color_scale"] = float(v[0]), float(v[1])
        return out
    if kind not in _TF_COLUMNS:
        raise Error("IVR_ERROR_INVALID_ARGUMENT", f"tf: unknown TF type {kind!r}")
    rows = {"piecewise_linear": "points", "table": "entries", "gaussian": "gaussians"}[kind]
    want = (len(tf[rows]), _TF_COLUMNS[kind])
    if values.shape != want:
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"tf: a {kind} TF of {want[0]} rows takes shape {want}, got {values.shape}")
    for r, row in enumerate(values.tolist()):
        if kind == "table":
            out["entries"][r] = row
        else:
            item = out[rows][r]
            item["color"], item["extinction"] = row[:3], row[3]
            if kind == "gaussian":
                item["mean"], item["width"] = row[4], row[5]
    return out


def tf_parameters(tf):
    """The differentiable parameters of a TF dict, in the TF gradient's layout (a float64 numpy
    array): the starting value of a `tf` tensor."""
    kind = tf.get("type")
    if kind == "identity":
        return np.array([tf.get("extinction_scale", 1.0), tf.get("color_scale", 1.0)])
    if kind == "table":
        return np.array(tf["entries"], dtype=np.float64)
    if kind == "piecewise_linear":
        return np.array([list(p["color"]) + [p["extinction"]] for p in tf["points"]])
    if kind == "gaussian":
        return np.array([list(g["color"]) + [g["extinction"], g["mean"], g["width"]]
                         for g in tf["gaussians"]])
    raise Error("IVR_ERROR_INVALID_ARGUMENT", f"tf: unknown TF type {kind!r}")


def _scene_dict(scene):
    if isinstance(scene, str):
        try:
            return json.loads(scene)
        except json.JSONDecodeError:
            with open(scene) as f:
                return json.load(f)
    return json.loads(json.dumps(scene))


class _Resident(torch.nn.Module):
    """A module that owns one ivr.Session of `scene` (its own context unless one is given)."""

    def __init__(self, scene, context=None, precision="f32", **session_options):
        super().__init__()
        self.scene = _scene_dict(scene)
        self.context = context if context is not None else Context(precision=precision)
        self.precision = precision
        self.session = Session(self.context, self.scene, precision=precision, **session_options)
        self._real = np.float64 if precision == "f64" else np.float32
        self._state = 0  # which forward's tensors the session holds
        # Whether the device reaches host memory itself: then arrays are wrapped and mapped.
        self.zero_copy = DeviceArray.wrap(self.session, np.zeros(1, self._real)).borrowed

    def _in(self, array):
        """A host array for an operation as a device array of its own dtype (a numpy array given
        to Session.gradient would become float32): the device reads its memory where it can,
        else it is uploaded once."""
        if self.zero_copy:
            return DeviceArray.wrap(self.session, array)
        return DeviceArray.from_numpy(self.session, array)

    def _out(self, array, like=None):
        """A result as a tensor (of `like`'s dtype and device): over the mapped device memory
        where the device's memory is the host's, else downloaded."""
        out = torch.from_numpy(array.view() if self.zero_copy else array.numpy())
        return out if like is None else out.to(dtype=like.dtype, device=like.device)

    def close(self):
        """Releases the session now (also done when the module is garbage-collected)."""
        self.session.close()


class _RenderFunction(torch.autograd.Function):
    @staticmethod
    def forward(ctx, renderer, density, tf, background, camera):
        renderer._apply_inputs(density, tf, background, camera)
        ctx.renderer, ctx.state = renderer, renderer._state
        ctx.given = tuple(t is not None for t in (density, tf, background, camera))
        ctx.save_for_backward(*(t for t in (density, tf, background, camera) if t is not None))
        image = renderer._out(renderer.session.render())
        like = next((t for t in (density, tf, background, camera) if t is not None), None)
        return image if like is None else image.to(device=like.device)

    @staticmethod
    def backward(ctx, grad_image):
        renderer = ctx.renderer
        saved = iter(ctx.saved_tensors)
        inputs = [next(saved) if g else None for g in ctx.given]
        if renderer._state != ctx.state:  # another forward has run since: set this one's again
            renderer._apply_inputs(*inputs)
        names = ("density", "tf", "background", "camera")
        wrt = [n for n, t, need in zip(names, inputs, ctx.needs_input_grad[1:])
               if t is not None and need]
        grads = [None] * 4
        if wrt:
            weights = renderer._in(_host(grad_image, renderer._real, "grad_output"))
            info = {}
            _, g = renderer.session.gradient(target=weights, wrt=wrt, mode=renderer.mode,
                                             loss="dot", info=info)
            renderer.last_mode = info["mode"]
            for name in wrt:
                i = names.index(name)
                grads[i] = renderer._out(g[name], inputs[i]).reshape(inputs[i].shape)
        return (None, *grads)


class Renderer(_Resident):
    """Renders a scene's every view as a differentiable function of its densities, TF,
    background and cameras (see the module's text). `mode`: "auto" (the planner's choice),
    "forward" or "adjoint". `precision` "f32" or "f64" (gradcheck); other keywords go to
    ivr.Session (step, empty_space, ...)."""

    def __init__(self, scene, context=None, precision="f32", mode="auto", **session_options):
        super().__init__(scene, context, precision, **session_options)
        self.mode = mode
        self.last_mode = None  # the mode the last backward ran ("forward" or "adjoint")
        self._cameras = self.scene.get("cameras", [])

    def forward(self, density=None, tf=None, background=None, camera=None):
        return _RenderFunction.apply(self, density, tf, background, camera)

    def tf_parameters(self):
        """The scene's TF parameters as a float64 tensor (the starting value of `tf`)."""
        return torch.from_numpy(tf_parameters(self.scene["tf"]))

    def camera_parameters(self):
        """The scene's cameras as a float64 (views, 7) tensor [eye, target, fov_y]."""
        self._listed_cameras()
        return torch.tensor([list(c["eye"]) + list(c.get("target", [0, 0, 0])) +
                             [c.get("fov_y", 45.0)] for c in self._cameras], dtype=torch.float64)

    def _listed_cameras(self):
        if not self._cameras or any("orbit" in c for c in self._cameras):
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        "camera: a camera tensor needs the scene's cameras listed one by one "
                        "(an orbit's cameras are not differentiable inputs)")

    def _apply_inputs(self, density, tf, background, camera):
        s = self.session
        if density is not None:
            s.set_volume(_host(density, self._real, "density"))
        if tf is not None:
            s.set_tf(_tf_with(self.scene["tf"], _host(tf, np.float64, "tf")))
        if background is not None:
            b = _host(background, np.float64, "background").reshape(-1)
            absorption = self.scene.get("model") == "absorption"
            if b.size != (1 if absorption else 3):
                raise Error("IVR_ERROR_INVALID_ARGUMENT",
                            f"background: {'(1,) I_in' if absorption else '(3,) RGB'} for this "
                            f"scene's model, got shape {tuple(background.shape)}")
            s.set_background(b)
        if camera is not None:
            self._listed_cameras()
            c = _host(camera, np.float64, "camera")
            if c.shape != (len(self._cameras), 7):
                raise Error("IVR_ERROR_INVALID_ARGUMENT",
                            f"camera: shape ({len(self._cameras)}, 7) [eye, target, fov_y] for "
                            f"the scene's cameras, got {c.shape}")
            cams = []
            for base, row in zip(self._cameras, c.tolist()):
                cam = dict(base)
                cam["eye"], cam["target"], cam["fov_y"] = row[:3], row[3:6], row[6]
                cams.append(cam)
            s.set_cameras(cams)
        self._state += 1


class _LinearFunction(torch.autograd.Function):
    """N v (transpose False) or N^T p (transpose True); the backward is the other one."""

    @staticmethod
    def forward(ctx, projector, x, transpose):
        ctx.projector, ctx.transpose = projector, transpose
        return _apply_projector(projector, x, transpose, "lines" if transpose else "volume")

    @staticmethod
    def backward(ctx, grad):
        return None, _apply_projector(ctx.projector, grad, not ctx.transpose, "grad_output"), None


def _apply_projector(p, x, transpose, what):
    op = p.session.backproject if transpose else p.session.project
    return p._out(op(p._in(_host(x, p._real, what))), x)


class Projector(_Resident):
    """The absorption projector of a scene's rays on its grid: forward(volume) = N v
    (views, H, W, 1) and transpose(lines) = N^T p (Z, Y, X), exact and each other's adjoint.
    The grid is the scene's volume, or `grid=(Z, Y, X)` (zeros in the default box)."""

    def __init__(self, scene, context=None, precision="f32", grid=None):
        scene = _scene_dict(scene)
        if grid is not None:
            scene = dict(scene)
            scene.pop("volume", None)
        super().__init__(scene, context, precision)
        if grid is not None:
            self.session.set_volume(np.zeros(tuple(int(d) for d in grid), self._real))
        if self.session.volume_shape == (0, 0, 0):
            raise Error("IVR_ERROR_INVALID_ARGUMENT",
                        "Projector: the scene has no volume; give grid=(Z, Y, X)")

    def forward(self, volume):
        return project(self, volume)

    def transpose(self, lines):
        return backproject(self, lines)


def _projector(p):
    if not isinstance(p, Projector):
        raise Error("IVR_ERROR_INVALID_ARGUMENT",
                    f"expected an ivr.torch.Projector, got {type(p).__name__}")
    return p


def project(projector, volume):
    """N v: line integrals of `volume` (Z, Y, X) along the projector's rays, (views, H, W, 1);
    its backward is backproject."""
    return _LinearFunction.apply(_projector(projector), volume, False)


def backproject(projector, lines):
    """N^T p of `lines` (views, H, W, 1) onto the projector's grid, (Z, Y, X); its backward is
    project."""
    return _LinearFunction.apply(_projector(projector), lines, True)
