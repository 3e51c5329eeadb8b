#!/usr/bin/env bash
# Soak run (not part of CI): `viscd run` for many frames while its memory is sampled.
# Writes OUT/memory.csv (seconds, frame, rss_kib, vm_kib), OUT/run.log and, with matplotlib,
# OUT/memory.png; prints the first, median and last resident size and the growth after warm-up.
# Usage: scripts/soak.sh [FRAMES] [OUT] [-- extra viscd run options]
#   e.g. scripts/soak.sh 100000 soak-out -- --objects 10000
set -euo pipefail
cd "$(dirname "$0")/.."
frames="${1:-100000}"
out="${2:-soak-out}"
shift $(($# < 2 ? $# : 2))
[[ "${1:-}" == "--" ]] && shift
viscd="${VISCD:-./build/release/viscd}"
[[ -x "$viscd" ]] || { echo "soak: $viscd not built (cmake --build --preset release)" >&2; exit 1; }
mkdir -p "$out"
# Run a copy, so that a rebuild during the soak does not change the binary under it.
cp "$viscd" "$out/viscd"
: >"$out/run.log"
"$out/viscd" run --frames "$frames" --out "$out/run" --backend cpu "$@" >"$out/run.log" 2>&1 &
pid=$!
trap 'kill "$pid" 2>/dev/null || true' EXIT
echo "seconds,frames_done,rss_kib,vm_kib" >"$out/memory.csv"
start=$(date +%s)
while kill -0 "$pid" 2>/dev/null; do
  rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  vm=$(awk '/^VmSize:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  done_frames=$(tr '\r' '\n' <"$out/run.log" | grep -oE '^frames [0-9]+' | tail -n1 | cut -d' ' -f2 || true)
  [[ -n "$rss" ]] && echo "$(($(date +%s) - start)),${done_frames:-0},$rss,$vm" >>"$out/memory.csv"
  sleep 5
done
wait "$pid"
rc=$?
trap - EXIT
echo "soak: viscd run exited $rc after $(($(date +%s) - start)) s"
# Debian's matplotlib belongs to the system python; prefer it over another python3 on PATH.
py=python3
[[ -x /usr/bin/python3 ]] && py=/usr/bin/python3
"$py" - "$out" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1] + "/memory.csv")))
rss = [int(r["rss_kib"]) for r in rows]
if len(rss) < 3:
    sys.exit("soak: too few samples")
warm = rss[len(rss) // 10:]  # after the first tenth (buffers reach their size in the first frames)
print(f"soak: {len(rss)} samples; RSS first {rss[0]} KiB, median {statistics.median(rss):.0f} KiB, "
      f"last {rss[-1]} KiB; after warm-up min {min(warm)} max {max(warm)} KiB "
      f"(growth {max(warm) - min(warm)} KiB)")
try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = [int(r["seconds"]) for r in rows]
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.plot(t, [v / 1024 for v in rss], label="resident (RSS)")
    ax.set_xlabel("seconds")
    ax.set_ylabel("MiB")
    ax.set_ylim(0, max(rss) / 1024 * 1.2)
    ax.set_title("viscd run: memory during the soak")
    ax.legend()
    fig.tight_layout()
    fig.savefig(sys.argv[1] + "/memory.png", dpi=110)
except ImportError:
    print("soak: matplotlib missing, no plot")
PY
exit "$rc"
