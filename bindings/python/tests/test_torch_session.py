"""test_torch_session.py — examples/python/torch_session.py: the autograd Function over one
ivr.Session gives, through torch's own machinery, the session's density gradient, and Adam
through it lowers the loss. Needs torch: it runs under Debian's python3 with python3-torch
(scripts/install-deps.sh installs it) and under .venv-bench (scripts/bench_setup.sh), and is
skipped where torch is missing."""
import importlib.util
import os
import subprocess
import sys

import numpy as np
import pytest

import ivr

torch = pytest.importorskip("torch")

EXAMPLE = os.path.join(os.path.dirname(__file__), "../../../examples/python/torch_session.py")


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("torch_session", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def ctx():
    with ivr.Context() as c:
        yield c


def test_autograd_gradient_is_the_sessions(example, ctx):
    session, true = example.make_problem(ctx, size=12, views=3, resolution=16)
    start = np.clip(true + 0.2 * np.random.default_rng(0).random(true.shape), 0, None)
    volume = torch.tensor(start.astype(np.float32), requires_grad=True)
    loss = example.SessionLoss.apply(volume, session)
    assert loss.shape == () and loss.dtype == torch.float32
    (g,) = torch.autograd.grad(3 * loss + 1, volume)  # the chain rule scales it by 3
    assert g.shape == volume.shape and g.dtype == torch.float32
    # the same session, asked directly at the same densities
    session.set_volume(start.astype(np.float32))
    want_loss, want = session.gradient(wrt=("density",), mode="adjoint")
    want = want["density"].numpy().astype(np.float64)
    assert loss.item() == pytest.approx(float(want_loss), rel=1e-6)
    np.testing.assert_allclose(g.numpy(), 3 * want, rtol=1e-5, atol=1e-5 * np.abs(3 * want).max())
    assert np.abs(want).max() > 0
    # backward through a longer graph: d/dv (loss^2) = 2 loss * dloss/dv
    v2 = volume.detach().clone().requires_grad_(True)
    (example.SessionLoss.apply(v2, session) ** 2).backward()
    np.testing.assert_allclose(v2.grad.numpy(), 2 * loss.item() * want, rtol=1e-5,
                               atol=1e-5 * np.abs(2 * loss.item() * want).max())


def test_adam_lowers_the_loss_in_ten_steps(example, ctx):
    session, true = example.make_problem(ctx, size=12, views=3, resolution=16)
    start = np.full(true.shape, 0.2, np.float32)
    volume, losses = example.reconstruct(session, start, iterations=10, lr=0.03)
    assert len(losses) == 10 and all(np.isfinite(losses))
    assert losses[-1] < 0.3 * losses[0], losses
    assert volume.min().item() >= 0
    # one session throughout: its densities are the last forward's (before the final step)
    assert session.volume_shape == true.shape
    assert np.linalg.norm(volume.numpy() - true) < np.linalg.norm(start - true)


def test_example_runs_as_a_script():
    r = subprocess.run([sys.executable, EXAMPLE, "--iterations", "6", "--size", "10"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "loss" in r.stdout and "->" in r.stdout
