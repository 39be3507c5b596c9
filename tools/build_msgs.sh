#!/usr/bin/env bash
# Build the hair_sim_msgs rosidl package (msg_defs/) with plain CMake into the venv prefix.
# Usage: tools/build_msgs.sh VENV_DIR BUILD_DIR
set -euo pipefail
venv=$(cd "$1" && pwd)
build=$2
py="$venv/bin/python"

# The message wheels export the Python and numpy include directories of the machine that
# built them (/opt/python/cp311-cp311/...); point them at this interpreter's so CMake's
# generate step accepts the imported targets. Idempotent: a fixed file has no match left.
inc=$("$py" -c "import sysconfig; print(sysconfig.get_paths()['include'])")
npinc=$("$py" -c "import numpy; print(numpy.get_include())")
old_inc=/opt/python/cp311-cp311/include/python3.11
old_npinc=/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include
{ grep -rlE "$old_inc|$old_npinc" "$venv/share" --include='*.cmake' || true; } \
  | while read -r f; do sed -i -e "s#${old_npinc}#${npinc}#g" -e "s#${old_inc}#${inc}#g" "$f"; done

mkdir -p "$build"
export AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv" PATH="$venv/bin:$PATH"
cmake -S msg_defs -B "$build" -DCMAKE_INSTALL_PREFIX="$venv" -DPython3_EXECUTABLE="$py" \
  -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release -Wno-dev > "$build.log" 2>&1 \
  || { tail -40 "$build.log"; exit 1; }
cmake --build "$build" -j "$(nproc)" >> "$build.log" 2>&1 || { tail -40 "$build.log"; exit 1; }
cmake --install "$build" >> "$build.log" 2>&1 || { tail -40 "$build.log"; exit 1; }
"$py" -c "import hair_sim_msgs.msg, hair_sim_msgs.srv" || { echo "hair_sim_msgs built but does not import"; exit 1; }
echo "hair_sim_msgs installed into $venv"
