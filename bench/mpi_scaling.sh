#!/usr/bin/env bash
# The distributed detector's scaling runs (docs/mpi.md, "Measured"): strong and weak scaling at
# 1 and 2 ranks (one thread per core in all), the halo share and bytes at 4 and 8 ranks
# (oversubscribed on a 2-core machine: their times mean nothing there, their counts do).
# Usage: bench/mpi_scaling.sh BUILD_DIR OUT.csv [CORES]
set -euo pipefail
build="$1"
out="$2"
cores="${3:-$(nproc)}"
bench="$build/bench/viscd_mpi_bench"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
rm -f "$out"
run() {  # run RANKS ARGS...
  local k="$1"
  shift
  local threads=$((cores / k))
  ((threads >= 1)) || threads=1
  echo "mpirun -np $k viscd_mpi_bench --threads $threads $*" >&2
  mpirun -np "$k" --bind-to none "$bench" --threads "$threads" --csv "$out" "$@" | tail -n +2
}
echo "mode,ranks,objects,objects_per_rank,frame_ms,exchange_ms,communication_ms,detect_ms,halo_share,bytes_sent_per_rank,plain_ms,pairs" >"$out"
for k in 1 2 1 2; do run "$k" --mode strong --objects 100000,1000000,10000000 --frames 7; done
for k in 1 2 1 2; do run "$k" --mode weak --objects 500000 --frames 7; done
for k in 4 8; do run "$k" --mode strong --objects 1000000,10000000 --frames 3 --warmup 1; done
