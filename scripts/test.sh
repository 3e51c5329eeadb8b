#!/usr/bin/env bash
# The README's second command: install what is missing, build, run every test.
# Usage: scripts/test.sh [preset]      preset: release (default), debug, asan, fuzz (libFuzzer, Clang)
#                                      or tsan (ThreadSanitizer: queries from many threads)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
scripts/setup.sh
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" --parallel "$(nproc)"
ctest --preset "$preset" --parallel "$(nproc)"
