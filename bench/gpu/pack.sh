#!/usr/bin/env bash
# Copies what the GPU machine needs out of a build folder into .dev/ (git-ignored): the tool, the
# gl/cuda/conformance test binaries, the benches, and the shared libraries of this machine that the
# GPU machine's image lacks (libepoxy, libstb). docs/gpu.md says how it is used.
# Usage: bench/gpu/pack.sh [BUILD_DIR]   (default build/device)
set -euo pipefail
build=${1:-build/device}
rm -rf .dev && mkdir -p .dev/lib
for f in viscd viscd_peers viscd_engine_bench tests/viscd_gl_tests tests/viscd_conformance_tests \
         tests/viscd_cuda_tests viscd_cuda_bench; do
  for d in "$build" "$build/bench"; do [ -x "$d/$f" ] && cp "$d/$f" .dev/; done
done
for lib in libepoxy.so.0 libstb.so.0; do
  cp -L "/lib/x86_64-linux-gnu/$lib" .dev/lib/
done
du -sh .dev
