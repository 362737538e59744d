#!/usr/bin/env bash
# Installs what the project needs into .venv (repository root) and builds the package into it.
#   scripts/setup_env.sh deps   - pinned Python + ROS 2 Kilted wheels: requirements-lab.txt (the
#                                 lab's), which includes requirements.txt (the product's), and
#                                 requirements-test.txt (pytest, ruff, selenium, ...);
#                                 PRODUCT=1: requirements.txt only (no torch, Ray, matplotlib)
#                                 and the test tools;
#                                 TORCH=cpu (default) first installs the pinned torch from the
#                                 PyTorch CPU index (TORCH_CPU_INDEX) where that answers within
#                                 5 s, else takes what pip's own indexes give (here: a local
#                                 wheel folder with the CPU build); TORCH=cuda the CUDA build
#                                 from TORCH_INDEX (default the PyTorch CUDA 12.8 index); either
#                                 way it ends saying which torch build it installed
#   scripts/setup_env.sh browser - headless chromium + chromedriver via apt (root only; for the
#                                 report's browser test), also run by `deps`
#   scripts/setup_env.sh build  - colcon build of the ROS package `tactex` (interfaces, Python
#                                 package, launch/config, node executables) merged into .venv,
#                                 then `bytecode`
#   scripts/setup_env.sh bytecode - compiles every module of .venv and the repository once
# The Makefile calls these only when their inputs changed, so a second run installs nothing.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=$ROOT/.venv
PYTHON=${PYTHON:-python3}

deps() {
  if [ ! -x "$VENV/bin/python" ]; then
    "$PYTHON" -m venv "$VENV"
  fi
  local reqs=requirements-lab.txt
  if [ "${PRODUCT:-0}" = 1 ]; then
    reqs=requirements.txt
  fi
  local pin
  pin=$(grep -E '^torch==' requirements-lab.txt)
  case "${TORCH:-cpu}" in
    cpu) [ "$reqs" = requirements.txt ] || torch_cpu "$pin" ;;
    cuda) [ "$reqs" = requirements.txt ] && { echo "setup_env: PRODUCT=1 installs no torch:" \
            "TORCH=cuda needs the lab" >&2; exit 2; }
      # the pinned version's CUDA build (e.g. 2.13.0+cu128); requirements-lab.txt's torch==2.13.0
      # is then already satisfied (a local version label matches the plain pin)
      "$VENV/bin/python" -m pip install --disable-pip-version-check -q "$pin" \
        --index-url "${TORCH_INDEX:-https://download.pytorch.org/whl/cu128}" ;;
    *) echo "setup_env: TORCH=${TORCH}: choose cpu or cuda" >&2; exit 2 ;;
  esac
  # --no-compile: pip compiles every file of every wheel on one core (100 s instead of 167 s
  # on this 2-core machine); `bytecode`, after the build, compiles them on both (34 s).
  "$VENV/bin/python" -m pip install --disable-pip-version-check --no-compile -q -r "$reqs" \
    -r requirements-test.txt
  torch_build
  # The ROS wheels' exported CMake files name the wheel builder's include dirs; point them at ours.
  local py_inc np_inc
  py_inc=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  np_inc=$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
  { grep -l '/opt/python/cp311-cp311' "$VENV"/share/*/cmake/*.cmake 2>/dev/null || true; } | while read -r f; do
    sed -i \
      -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#${np_inc}#g" \
      -e "s#/opt/python/cp311-cp311/include/python3.11#${py_inc}#g" "$f"
  done
}

torch_cpu() {   # $1: the pin. PyPI's plain torch wheel is the CUDA build (GBs): ask the CPU index
  local index=${TORCH_CPU_INDEX:-https://download.pytorch.org/whl/cpu}
  if "$VENV/bin/python" - "$index" <<'EOF'
import sys
import urllib.request
try:
    urllib.request.urlopen(sys.argv[1].rstrip("/") + "/", timeout=5).close()
except OSError:
    raise SystemExit(1)
EOF
  then
    echo "setup_env: $1 from the CPU index $index"
    "$VENV/bin/python" -m pip install --disable-pip-version-check --no-compile -q "$1" \
      --index-url "$index"
  else
    echo "setup_env: the CPU index $index did not answer within 5 s: $1 from pip's" \
         "configured indexes (the CPU build only where one of them serves it)" >&2
  fi
}

torch_build() {   # which torch build the lab got (nothing where none is installed: PRODUCT=1)
  "$VENV/bin/python" - <<'EOF'
import importlib.util
if importlib.util.find_spec("torch") is not None:
    import torch
    cuda = torch.version.cuda
    print(f"setup_env: torch {torch.__version__}, "
          + (f"the CUDA {cuda} build" if cuda else "the CPU build (no CUDA)"))
EOF
}

browser() {
  # headless Chromium + chromedriver for the report's browser test (test/ros/test_session.py);
  # installed with apt where this runs as root, else the test is skipped with the reason
  if command -v chromium >/dev/null && command -v chromedriver >/dev/null; then
    return 0
  fi
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver \
      || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
           chromium chromium-driver; } \
      || echo "setup_env: chromium not installed (apt failed); the browser test will skip" >&2
  else
    echo "setup_env: chromium/chromedriver missing and not root: install them (apt install" \
         "chromium chromium-driver) or the report's browser test skips" >&2
  fi
}

build() {
  export PATH="$VENV/bin:$PATH"
  export CMAKE_PREFIX_PATH="$VENV"
  export AMENT_PREFIX_PATH="$VENV"
  "$VENV/bin/colcon" --log-base "$ROOT/.colcon/log" build \
    --base-paths "$ROOT" \
    --build-base "$ROOT/.colcon/build" \
    --install-base "$VENV" \
    --merge-install --symlink-install \
    --event-handlers console_cohesion- status- summary+ \
    --cmake-args -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF
  ln -sf ../lib/tactex/tactex "$VENV/bin/tactex"
  bytecode
}

bytecode() {
  # Every module's bytecode, compiled once here on both cores (pip --no-compile above). Where
  # PYTHONDONTWRITEBYTECODE is set (this project's machines set it), no process ever writes
  # it, and each one compiles every module it imports from source: `import torch` 4.6 s
  # instead of 1.8 s, and every node of every test graph pays the same for numpy, rclpy and
  # the rest. Measured on a fresh clone: 34 s for the whole .venv. An up-to-date file is
  # skipped, so a rebuild costs seconds. compileall's exit status is not checked: some wheels
  # ship files for a newer Python (torch's py312_intrinsics.py) that no import reaches.
  local site
  site=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  "$VENV/bin/python" -m compileall -q -j 0 "$site" "$ROOT/tactex_ros" "$ROOT/tactex_lab" \
    >/dev/null 2>&1 || true
}

case "${1:-all}" in
  deps) deps; browser ;;
  build) build ;;
  bytecode) bytecode ;;
  browser) browser ;;
  all) deps; browser; build ;;
  *) echo "usage: $0 [deps|build|bytecode|browser|all]" >&2; exit 2 ;;
esac
