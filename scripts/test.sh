#!/usr/bin/env bash
# The README's second command: install what is missing, build, run every test (and, for the
# release preset, the Python module installed by pip into a virtual environment).
# Usage: scripts/test.sh [preset]      preset: release (default), debug, asan, fuzz (libFuzzer, Clang)
#                                      or tsan (ThreadSanitizer: queries from many threads)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
scripts/setup.sh
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" --parallel "$(nproc)"
ctest --preset "$preset" --parallel "$(nproc)"
# The Python module as users install it: pip into a fresh virtual environment, tests from there.
if [[ "$preset" == release ]]; then scripts/python_install_test.sh; fi
