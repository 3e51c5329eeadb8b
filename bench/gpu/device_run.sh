#!/usr/bin/env bash
# Runs on the GPU machine (the device tool), from the repository root, over what bench/gpu/pack.sh
# put in .dev/ and the EGL loader packages in .gl/ (docs/gpu.md). Each step has its own time limit
# and the script goes on after a failure; everything lands in $OUT/results.tgz, the last lines
# printed are a short summary.
# Usage: bench/gpu/device_run.sh STEP...
#   steps: env gltests conformance paper stages frame splat cuda cudapaper cudaenv cudabig
#   (cudaenv: env without the GL probe; cudabig: CudaBroadphase at 10^8 objects, on an H200)
set -uo pipefail
OUT=${OUT:-/tmp/out}
R=/tmp/res
mkdir -p "$R" "$OUT"
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
export LD_LIBRARY_PATH=$PWD/.dev/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
[ -f /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json ] &&
  export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
D=$PWD/.dev
summary=()

step() {  # step NAME TIMEOUT_S CMD...
  local name=$1 limit=$2
  shift 2
  local t0=$SECONDS
  timeout "$limit" "$@" >"$R/$name.log" 2>&1
  local rc=$?
  summary+=("$(printf '%-28s rc=%-3s %4ss' "$name" "$rc" "$((SECONDS - t0))")")
  echo "== $name rc=$rc ($((SECONDS - t0)) s)"
  tail -n 3 "$R/$name.log"
}

paper() {  # paper BACKEND [OPTIONS]: the paper's tables and figures to 10^6 objects
  local b=$1
  shift
  step "paper_$b" 420 "$D/viscd" bench paper --backend "$b" \
    --sizes 1000,2000,5000,10000,20000,50000,100000,200000,500000,1000000 --frames 20 --warmup 5 --out "$R/paper_$b" "$@"
}

stages() {  # stages BACKEND...: every object active, 32 bits, ring and dense, 10^4..10^7 objects
  local scene n b frames
  for scene in ring:0.04 dense:0.18; do
    for n in 10000 100000 1000000 10000000; do
      frames=40
      [ "$n" = 10000000 ] && frames=10
      for b in "$@"; do
        step "stages_${scene%%:*}_${b}_$n" 200 "$D/viscd" run --backend "$b" --objects "$n" --packing "${scene##*:}" \
          --no-culling --bits 32 --frames "$frames" --out "$R/stages_${scene%%:*}_${b}_$n" -q
      done
    done
  done
}

frames() {  # frames BACKEND...: 10^6 objects with culling from the three cameras
  local b cam
  for b in "$@"; do
    for cam in zoom-out orbit zoom-in; do
      step "frame_${b}_${cam}_1m" 200 "$D/viscd" run --backend "$b" --objects 1000000 --camera "$cam" --frames 40 \
        --out "$R/frame_${b}_${cam}_1m" -q
    done
  done
}

for s in "$@"; do
  case $s in
    env)
      step env 60 bash -c "date -u; nvidia-smi; nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.max.mem --format=csv;
        ldd --version | head -1; nproc; free -g; ldd $D/viscd | grep -i 'not found'; $D/viscd run --backend gl --objects 1000 --frames 2 --out $R/probe" ;;
    gltests) step gl_tests 240 "$D/viscd_gl_tests" --gtest_brief=1 ;;
    conformance) step conformance 300 "$D/viscd_conformance_tests" --gtest_brief=1 ;;
    paper) paper gl ;;
    stages) stages gl cpu ;;
    frame) frames gl cpu ;;
    splat)
      for n in 10000 100000 1000000; do
        for g in impostor splat; do
          for cam in zoom-out orbit zoom-in; do
            step "geom_${g}_${cam}_$n" 200 "$D/viscd" run --backend gl --geometry "$g" --objects "$n" --camera "$cam" \
              --frames 40 --out "$R/geom_${g}_${cam}_$n" -q
          done
        done
      done ;;
    cudaenv)
      step env 60 bash -c "date -u; nvidia-smi; nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.max.mem --format=csv;
        ldd --version | head -1; nproc; free -g" ;;
    cudabig) step cuda_bench_1e8 300 "$D/viscd_cuda_bench" --parts device --device 100000000 --frames 5 --warmup 1 \
      --csv "$R/cuda_bench_1e8.csv" ;;
    cuda)
      step cuda_tests 240 "$D/viscd_cuda_tests" --gtest_brief=1
      step conformance_cuda 300 "$D/viscd_conformance_tests" --gtest_brief=1 --gtest_filter='cuda/*'
      step cuda_bench 300 "$D/viscd_cuda_bench" --csv "$R/cuda_bench.csv" ;;
    cudapaper)
      paper cuda --no-plots
      stages cuda
      frames cuda ;;
  esac
done
(cd "$R" && find . -name "*.json" -o -name "*.csv" -o -name "*.log" -o -name "fig5_*.png" | tar czf "$OUT/results.tgz" -T -)
printf '%s\n' "${summary[@]}"
