#!/usr/bin/env bash
# bench_setup.sh — creates the Python virtual environment ivr-bench's baselines run in (JAX, Dr.Jit,
# PyTorch CPU, numpy, pytest, matplotlib); safe to run again.
#
#   scripts/bench_setup.sh [--venv PATH] [--with-torch-pypi]
#
# PyTorch comes from its CPU wheel index. When that index cannot be reached, torch is skipped (the
# torch baseline then reports itself unavailable) unless --with-torch-pypi is given: PyPI's Linux
# wheel is the CUDA build and pulls several GB of nvidia-* packages, which the CPU benchmark never uses.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$root/.venv-bench"
torch_pypi=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --venv) venv="$2"; shift 2 ;;
    --venv=*) venv="${1#--venv=}"; shift ;;
    --with-torch-pypi) torch_pypi=1; shift ;;
    -h|--help) sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "bench_setup.sh: unknown option $1" >&2; exit 2 ;;
  esac
done

# The system Python when there is one (Debian's, with a working venv/ensurepip), else PATH's.
if [[ -x /usr/bin/python3 ]]; then base_python=/usr/bin/python3; else base_python=python3; fi

if [[ ! -x "$venv/bin/python" ]]; then
  echo "== creating $venv with $base_python ($("$base_python" --version 2>&1))"
  "$base_python" -m venv "$venv"
fi
py="$venv/bin/python"
pip=("$py" -m pip --disable-pip-version-check)

echo "== installing numpy, pytest, matplotlib, jax[cpu], drjit"
"${pip[@]}" install --upgrade pip >/dev/null
"${pip[@]}" install numpy pytest matplotlib "jax[cpu]" drjit

torch_note=""
if "$py" -c "import torch" 2>/dev/null; then
  torch_note="torch already installed"
else
  echo "== installing torch (CPU wheel index)"
  if "${pip[@]}" install --timeout 30 --retries 1 torch \
      --index-url https://download.pytorch.org/whl/cpu; then
    torch_note="torch from the CPU wheel index"
  elif [[ $torch_pypi == 1 ]]; then
    echo "== the CPU wheel index is unreachable; installing torch from PyPI (CUDA build, several GB)"
    "${pip[@]}" install torch
    torch_note="torch from PyPI (CUDA build, run on the CPU)"
  else
    torch_note="torch NOT installed: the CPU wheel index (download.pytorch.org) is unreachable;
   rerun with --with-torch-pypi to install PyPI's CUDA build (several GB), or go without torch"
  fi
fi

echo "== $venv"
"$py" - <<'EOF'
import importlib, platform
print(f"  python      {platform.python_version()}")
for name in ("numpy", "pytest", "matplotlib", "jax", "jaxlib", "drjit", "torch"):
    try:
        module = importlib.import_module(name)
        extra = ""
        if name == "drjit":  # its CPU backend loads the system's libLLVM at run time
            llvm = module.has_backend(module.JitBackend.LLVM)
            extra = "  (LLVM backend ok)" if llvm else "  (no libLLVM found: apt-get install libllvm15)"
        print(f"  {name:<11} {module.__version__}{extra}")
    except Exception as e:  # noqa: BLE001 - a missing optional baseline is reported, not fatal
        print(f"  {name:<11} not available ({type(e).__name__})")
EOF
echo "  note: $torch_note"
