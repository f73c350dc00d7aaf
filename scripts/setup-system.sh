#!/usr/bin/env bash
# Installs the system packages idexp's build needs, only if they are missing
# (idempotent): cmake (nlopt builds its bundled C library with it), gfortran and
# libopenblas-dev (Clarabel's semidefinite cone links the system OpenBLAS), and
# chromium (headless, for the preview page's browser test, tests/preview.rs).
set -euo pipefail
need=()
command -v cmake >/dev/null 2>&1 || need+=(cmake)
command -v gfortran >/dev/null 2>&1 || need+=(gfortran)
dpkg -s libopenblas-dev >/dev/null 2>&1 || need+=(libopenblas-dev)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
if [ ${#need[@]} -gt 0 ]; then
  echo "idexp setup: installing ${need[*]}" >&2
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}" >/dev/null
fi
