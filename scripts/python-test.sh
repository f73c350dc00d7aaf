#!/usr/bin/env bash
# Builds the Python package (python/, maturin + pyo3) into a venv under
# target/python-venv and runs its pytest suite (python/tests/).
#
# Idempotent and offline-safe once installed: PyPI packages (maturin, numpy,
# pytest, matplotlib, pin = Pinocchio, example-robot-data, mujoco) are installed only when missing; the
# wheel is rebuilt (cargo's incremental build, in target/) and reinstalled each run.
# Extra arguments go to pytest (e.g. `-k pinocchio`).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup-system.sh
PY="${PYTHON:-python3}"
VENV=target/python-venv
if [ ! -x "$VENV/bin/python" ]; then
  "$PY" -m venv "$VENV"
fi
VPY="$VENV/bin/python"
# the maturin build backend runs the `maturin` of PATH: the venv's
export PATH="$PWD/$VENV/bin:$PATH"
if ! "$VPY" -c "import maturin, numpy, pytest, matplotlib, pinocchio, rosbags, mujoco, importlib.metadata as m; m.version('example-robot-data')" >/dev/null 2>&1; then
  echo "python-test: installing maturin numpy pytest matplotlib pin example-robot-data rosbags mujoco into $VENV" >&2
  "$VPY" -m pip install -q "maturin>=1.7,<2" numpy pytest matplotlib pin example-robot-data rosbags mujoco
fi
# the command-line binary the tests compare against
cargo build --release --bin idexp
# the README's install command, with the venv's maturin (no download: offline-safe)
"$VPY" -m pip install -q --no-build-isolation --force-reinstall --no-deps ./python
# from the repository root: `import idexp` is the installed wheel (python/idexp
# without the native module is not on sys.path)
exec "$VPY" -m pytest -q python/tests "$@"
