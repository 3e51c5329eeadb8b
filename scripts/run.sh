#!/usr/bin/env bash
# The README's first command: install what is missing, build (release), run the demo.
# Usage: scripts/run.sh [viscd run options...]     e.g. scripts/run.sh --objects 50000
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cmake --preset release >/dev/null
cmake --build --preset release --parallel "$(nproc)" -- --quiet 2>/dev/null || cmake --build --preset release --parallel "$(nproc)"
exec ./build/release/viscd run "$@"
