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

# The installed tool finds what `viscd bench` needs in the prefix, not in the build tree.
prefix="$work/prefix"
if [[ -x "$prefix/bin/viscd" ]]; then
  [[ -f "$prefix/share/viscd/plot_paper.py" ]] || { echo "FAIL: share/viscd/plot_paper.py not installed" >&2; exit 1; }
  if [[ -f "$build/viscd_peers" ]]; then
    [[ -x "$prefix/libexec/viscd/viscd_peers" ]] || { echo "FAIL: libexec/viscd/viscd_peers not installed" >&2; exit 1; }
    # Run from a copy of the prefix elsewhere, so that nothing next to the build tree is found.
    cp -r "$prefix" "$work/moved"
    "$work/moved/bin/viscd" bench peers -- --help >"$work/peers.txt"
    grep -q -- "--objects" "$work/peers.txt" || { echo "FAIL: installed viscd bench peers" >&2; exit 1; }
  fi
  echo "install test: bench scripts and the peers driver installed and found"
fi
