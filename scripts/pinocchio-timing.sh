#!/usr/bin/env bash
# Pinocchio side by side with idexp's kernels (docs/performance.md): the same
# UR5 and Panda URDFs, the same states, one thread. Builds a small C++ timing
# program against the headers and libraries of the PyPI wheel `pin`
# (Pinocchio) in the Python venv, runs idexp's criterion bench `robot` for
# those two robots (which also writes its states), then prints a table.
#
# The venv: target/python-venv (made by scripts/python-test.sh, which
# installs `pin`), or $PINOCCHIO_VENV. Needs g++ and the Eigen headers
# (Debian libeigen3-dev, installed here when missing).
#   scripts/pinocchio-timing.sh            # bench + Pinocchio + table
#   scripts/pinocchio-timing.sh --no-bench # reuse target/criterion figures
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${PINOCCHIO_VENV:-target/python-venv}"
VPY="$VENV/bin/python"
if ! "$VPY" -c "import pinocchio" >/dev/null 2>&1; then
  echo "pinocchio-timing: no Python with pinocchio at $VENV; make it with scripts/python-test.sh (or set PINOCCHIO_VENV)" >&2
  exit 1
fi
if [ ! -f /usr/include/eigen3/Eigen/Core ]; then
  echo "pinocchio-timing: installing libeigen3-dev" >&2
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libeigen3-dev >/dev/null
fi
TARGET="${CARGO_TARGET_DIR:-target}"
PREFIX="$("$VPY" -c 'import cmeel, os; print(os.path.join(os.path.dirname(cmeel.__file__), "..", "cmeel.prefix"))')"
PREFIX="$(cd "$PREFIX" && pwd)"
BIN="$TARGET/pinocchio-timing/pinocchio_timing"
SRC=scripts/pinocchio-timing/timing.cpp
mkdir -p "$TARGET/pinocchio-timing"
if [ ! -x "$BIN" ] || [ "$SRC" -nt "$BIN" ]; then
  echo "pinocchio-timing: building $BIN (g++ -O3, about a minute)" >&2
  # the compile definitions of the wheel's pinocchio CMake targets; the wheel's
  # CMake config itself needs urdfdom headers it does not ship, so the model
  # comes from Python (the wheel's URDF parser) as a binary archive
  g++ -O3 -DNDEBUG -std=c++17 -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION \
    -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30 \
    -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12 \
    -I"$PREFIX/include" -I/usr/include/eigen3 "$SRC" -o "$BIN" \
    -L"$PREFIX/lib" -lpinocchio_default -lboost_serialization -Wl,-rpath,"$PREFIX/lib"
fi
if [ "${1:-}" != "--no-bench" ]; then
  cargo bench --bench robot -- --warm-up-time 1 --measurement-time 3 '^(ur5_6dof|panda_7dof)/' >&2
fi
OMP_NUM_THREADS=1 exec "$VPY" scripts/pinocchio-timing.py "$BIN" "$TARGET"
