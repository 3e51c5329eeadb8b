#!/usr/bin/env bash
# Installs the built viscd into a scratch prefix, builds examples/game_loop.cpp against it with
# find_package(viscd) from a separate project, and runs it.
# Usage: install_test.sh BUILD_DIR WORK_DIR
set -euo pipefail
build="$1" work="$2"
here="$(cd "$(dirname "$0")" && pwd)"
rm -rf "$work" && mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" >/dev/null
cmake -S "$here" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/consumer" >/dev/null
"$work/consumer/game_loop" | tee "$work/out.txt"
grep -q "tick  *80:" "$work/out.txt"
echo "install test: find_package(viscd) + game_loop OK"
