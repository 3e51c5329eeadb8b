#!/usr/bin/env bash
# Command-line tests of the `viscd` tool: exit codes, outputs and messages of `pairs`, `query` and
# `run` (spheres, boxes and the static set), the backend choice (--backend auto, gl without
# OpenGL) and the cpu kernel options.
# Usage: VISCD=/path/to/viscd bash tests/apps/cli_test.sh WORKDIR
set -euo pipefail

source "$(dirname "$0")/cli_lib.sh"

# ----------------------------------------------------------------------------------------------
# Fixtures: four spheres; 0 and 1 touch (centres 1 apart, radii 0.5), 2 and 3 overlap, 1 and 2
# are far apart.
cat >"$W/four.xyzr" <<'EOF'
# x y z r
0 0 0 0.5
1 0 0 0.5   # touches sphere 0

100 0 0 1
101.5 0 0 1
EOF
cat >"$W/four.csv" <<'EOF'
x,y,z,r
0,0,0,0.5
1,0,0,0.5
100,0,0,1
101.5,0,0,1
EOF
cat >"$W/bad.xyzr" <<'EOF'
0 0 0 0.5
1 0 0 0.5
100 0 0
101.5 0 0 1
EOF
EXPECTED_PAIRS='i,j\n0,1\n2,3\n'

# ----------------------------------------------------------------------------------------------
step "viscd --help exits 0 and names the run and pairs commands"
expect_rc 0 --help
expect_in "$W/out" "run" "--help"
expect_in "$W/out" "pairs" "--help"
pass

step "viscd pairs --help mentions --spheres and ends with its own examples, not the tool's"
expect_rc 0 pairs --help
expect_in "$W/out" "--spheres" "pairs --help"
expect_in "$W/out" "viscd pairs --boxes crates.csv --static walls.csv" "pairs --help"
if grep -qF -- "viscd run --objects 100000" "$W/out"; then fail "pairs --help shows the tool's run examples"; fi
if [[ "$(tail -n 1 "$W/out")" != "Docs: docs/usage.md" ]]; then fail "pairs --help does not end with its own footer"; fi
pass

step "viscd run --help mentions --objects and --frames"
expect_rc 0 run --help
expect_in "$W/out" "--objects" "run --help"
expect_in "$W/out" "--frames" "run --help"
pass

step "viscd without a subcommand is a usage error (exit 2)"
expect_rc 2
pass

step "viscd with an unknown subcommand is a usage error (exit 2)"
expect_rc 2 frobnicate
pass

step "pairs finds exactly (0,1) touching and (2,3) overlapping"
expect_rc 0 pairs --spheres "$W/four.xyzr" --out "$W/pairs.csv" --stats "$W/stats.json"
expect_file_equals "$W/pairs.csv" "$EXPECTED_PAIRS" "pairs CSV"
pass

step "pairs --stats writes JSON with \"pairs\": 2"
[[ -s "$W/stats.json" ]] || fail "stats JSON $W/stats.json was not written"
expect_in "$W/stats.json" '"pairs": 2' "stats JSON"
expect_in "$W/stats.json" '"objects": 4' "stats JSON"
if command -v python3 >/dev/null 2>&1; then
  python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); assert d["pairs"]==2 and d["mean_pixels"] is None, d' \
    "$W/stats.json" || fail "stats JSON is not valid JSON with pairs 2 and null mean_pixels"
fi
pass

step "pairs prints a 16-hex-digit hash"
HASH="$(grep -oE 'hash [0-9a-f]{16}' "$W/out" | head -n1 | cut -d' ' -f2 || true)"
[[ -n "$HASH" ]] || { show pairs; fail "no 'hash <16 hex digits>' in the output of pairs"; }
echo "    hash $HASH"
pass

step "--validate-hash with the printed hash passes (exit 0)"
expect_rc 0 pairs --spheres "$W/four.xyzr" --out "$W/pairs_v.csv" --validate-hash "$HASH"
expect_file_equals "$W/pairs_v.csv" "$EXPECTED_PAIRS" "pairs CSV with --validate-hash"
pass

step "--validate-hash with a wrong hash exits 3 and says so"
WRONG="0000000000000000"
[[ "$HASH" != "$WRONG" ]] || WRONG="1111111111111111"
expect_rc 3 pairs --spheres "$W/four.xyzr" --out "$W/pairs_w.csv" --validate-hash "$WRONG"
expect_in "$W/err" "hash" "wrong hash message"
pass

step "a malformed file (line 3 has 3 numbers) exits 1 naming <file>:3:"
expect_rc 1 pairs --spheres "$W/bad.xyzr" --out "$W/pairs_bad.csv"
expect_in "$W/err" "$W/bad.xyzr:3:" "malformed file error"
pass

step "a missing file exits 1 naming it"
expect_rc 1 pairs --spheres "$W/no_such_file.xyzr" --out "$W/pairs_missing.csv"
expect_in "$W/err" "no_such_file.xyzr" "missing file error"
pass

step "pairs without --spheres is a usage error (exit 2)"
expect_rc 2 pairs --out "$W/pairs_none.csv"
pass

step "--bits 12 is a usage error (exit 2) naming --bits"
expect_rc 2 pairs --spheres "$W/four.xyzr" --out "$W/pairs_bits.csv" --bits 12
expect_in "$W/err" "--bits" "--bits 12 error"
pass

step "--bits 16, 32 and 64 give the same pairs"
for b in 16 32 64 adaptive; do
  expect_rc 0 pairs --spheres "$W/four.xyzr" --out "$W/pairs_b$b.csv" --bits "$b"
  expect_file_equals "$W/pairs_b$b.csv" "$EXPECTED_PAIRS" "pairs CSV with --bits $b"
done
pass

step "--backend nope is a usage error (exit 2)"
expect_rc 2 pairs --spheres "$W/four.xyzr" --out "$W/pairs_nope.csv" --backend nope
expect_in "$W/err" "nope" "--backend nope error"
pass

step "--backend reference gives the identical CSV"
expect_rc 0 pairs --spheres "$W/four.xyzr" --out "$W/pairs_ref.csv" --backend reference
expect_file_equals "$W/pairs_ref.csv" "$EXPECTED_PAIRS" "reference pairs CSV"
cmp -s "$W/pairs.csv" "$W/pairs_ref.csv" || fail "cpu and reference pairs CSVs differ"
pass

step "CSV input with a header gives the same pairs"
expect_rc 0 pairs --spheres "$W/four.csv" --out "$W/pairs_csv.csv"
expect_file_equals "$W/pairs_csv.csv" "$EXPECTED_PAIRS" "pairs from CSV input"
pass

step "an empty sphere file gives zero pairs"
: >"$W/empty.xyzr"
expect_rc 0 pairs --spheres "$W/empty.xyzr" --out "$W/pairs_empty.csv"
expect_file_equals "$W/pairs_empty.csv" 'i,j\n' "pairs CSV of an empty file"
pass

step "pairs with a camera JSON culls and still writes a valid CSV"
cat >"$W/cam.json" <<'EOF'
{"eye": [0.5, 0, 5], "target": [0.5, 0, 0], "up": [0, 1, 0], "fov_y_deg": 60, "near": 0.1,
 "far": 1000, "width": 640, "height": 360}
EOF
expect_rc 0 pairs --spheres "$W/four.xyzr" --camera "$W/cam.json" --out "$W/pairs_cam.csv" --stats "$W/stats_cam.json" --lambda 1
head -n1 "$W/pairs_cam.csv" | grep -qx 'i,j' || fail "pairs CSV with camera lacks the header i,j"
expect_in "$W/pairs_cam.csv" "0,1" "pairs with a camera (0 and 1 are in view and large)"
pass

step "a bad camera JSON exits 1 naming the file"
echo '{"eye": [0, 0, 10], "bogus": 1}' >"$W/badcam.json"
expect_rc 1 pairs --spheres "$W/four.xyzr" --camera "$W/badcam.json" --out "$W/pairs_badcam.csv"
expect_in "$W/err" "badcam.json" "bad camera error"
expect_in "$W/err" "bogus" "bad camera error"
pass

# ----------------------------------------------------------------------------------------------
step "run --objects 2000 --frames 3 writes a screenshot, frames.csv and summary.json"
expect_rc 0 run --objects 2000 --frames 3 --out "$W/run"
[[ -s "$W/run/screenshot.png" ]] || fail "run/screenshot.png missing or empty"
MAGIC="$(head -c 8 "$W/run/screenshot.png" | od -An -tx1 | tr -d ' \n')"
[[ "$MAGIC" == "89504e470d0a1a0a" ]] || fail "run/screenshot.png does not start with the PNG magic bytes (got $MAGIC)"
[[ -f "$W/run/frames.csv" ]] || fail "run/frames.csv missing"
LINES="$(wc -l <"$W/run/frames.csv")"
[[ "$LINES" -eq 4 ]] || { cat "$W/run/frames.csv" >&2; fail "run/frames.csv has $LINES lines, expected a header and 3 rows"; }
head -n1 "$W/run/frames.csv" | grep -q '^frame,' || fail "run/frames.csv header does not start with 'frame,'"
[[ -s "$W/run/summary.json" ]] || fail "run/summary.json missing or empty"
if command -v python3 >/dev/null 2>&1; then
  python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); assert d["objects"]==2000 and d["frames"]==3, d' \
    "$W/run/summary.json" || fail "run/summary.json is not valid JSON with objects 2000 and frames 3"
  # The memory: the detector's tally, and (where /proc has them) the frames' peak above the memory
  # before them.
  python3 -c 'import json,sys; m=json.load(open(sys.argv[1]))["memory"]; assert m["detector_bytes"] > 0, m
if "peak_rss_bytes" in m:
    assert m["peak_rss_bytes"] >= m["rss_before_frames_bytes"] > 0, m
    assert m["added_bytes_per_object"] == (m["peak_rss_bytes"] - m["rss_before_frames_bytes"]) / 2000, m' \
    "$W/run/summary.json" || fail "run/summary.json has no consistent memory figures"
fi
expect_in "$W/out" "memory: " "run prints its memory"
pass

step "run --camera zoom-in --frames 2 --map-size 320x180 works"
expect_rc 0 run --camera zoom-in --frames 2 --out "$W/run2" --map-size 320x180 --objects 2000
[[ -s "$W/run2/screenshot.png" ]] || fail "run2/screenshot.png missing"
LINES="$(wc -l <"$W/run2/frames.csv")"
[[ "$LINES" -eq 3 ]] || fail "run2/frames.csv has $LINES lines, expected a header and 2 rows"
pass

step "run --map-size 0x5 is a usage error (exit 2) with a message"
expect_rc 2 run --map-size 0x5 --frames 1 --objects 100 --out "$W/run3"
expect_in "$W/err" "--map-size" "--map-size 0x5 error"
pass

step "run --camera nope and --scene donut fail with messages"
expect_rc 2 run --camera nope --frames 1 --objects 100 --out "$W/run4"
expect_in "$W/err" "nope" "--camera nope error"
expect_rc 2 run --scene donut --frames 1 --objects 100 --out "$W/run5"
expect_in "$W/err" "donut" "--scene donut error"
pass

step "run --packing: the dense ring has more pairs; out of range is a usage error"
expect_rc 0 run --objects 3000 --frames 1 --no-culling --bits 32 --out "$W/pack1" --json "$W/pack1/s.json" --quiet
expect_rc 0 run --objects 3000 --frames 1 --no-culling --bits 32 --packing 0.18 --out "$W/pack2" --json "$W/pack2/s.json" --quiet
p1=$(sed -n 's/.*"pairs": \([0-9]*\).*/\1/p' "$W/pack1/s.json" | head -1)
p2=$(sed -n 's/.*"pairs": \([0-9]*\).*/\1/p' "$W/pack2/s.json" | head -1)
[ "$p2" -gt $((3 * p1)) ] || fail "--packing 0.18 gave $p2 pairs against $p1 at 0.04"
expect_rc 2 run --objects 100 --frames 1 --packing 0.9 --out "$W/pack3"
expect_in "$W/err" "--packing" "--packing 0.9 error"
pass

step "run --backend cuda: runs on a GPU, else fails (exit 1) saying why; never a usage error"
set +e
"$VISCD" run --backend cuda --objects 300 --frames 1 --out "$W/cuda" --quiet 2>"$W/err"
rc=$?
set -e
if [ "$rc" -ne 0 ]; then
  [ "$rc" -eq 1 ] || fail "--backend cuda exited $rc (want 0 on a GPU, 1 without)"
  expect_in "$W/err" "CUDA" "--backend cuda error"
fi
pass

step "run --frames 0 is a usage error (exit 2)"
expect_rc 2 run --frames 0 --objects 100 --out "$W/run6"
expect_in "$W/err" "--frames" "--frames 0 error"
pass

# ----------------------------------------------------------------------------------------------
# Filters, the caller's id map, queries, contact events and per-frame pairs.

# four.csv with filters: 0 and 1 touch but 1 (group 2, mask 0) collides with nothing; 2 and 3
# overlap and accept each other (2: group 1, mask 0x10; 3: group 0x10, mask 1).
cat >"$W/four_filters.csv" <<'CSV'
x,y,z,r,group,mask
0,0,0,0.5,1,0xFFFFFFFF
1,0,0,0.5,2,0
100,0,0,1,1,0x10
101.5,0,0,1,0x10,1
CSV
step "pairs honours group and mask columns: only (2,3)"
expect_rc 0 pairs --spheres "$W/four_filters.csv" --out "$W/pairs_f.csv"
expect_file_equals "$W/pairs_f.csv" 'i,j\n2,3\n' "filtered pairs"
expect_rc 0 pairs --spheres "$W/four_filters.csv" --out "$W/pairs_fr.csv" --backend reference
expect_file_equals "$W/pairs_fr.csv" 'i,j\n2,3\n' "filtered pairs, reference"
pass

step "a bad group or mask value exits 1 naming file:line and what was expected"
printf 'x,y,z,r,group,mask\n0,0,0,1,1,1\n0,0,0,1,1,0x1FFFFFFFF\n' >"$W/bad_mask.csv"
expect_rc 1 pairs --spheres "$W/bad_mask.csv" --out "$W/pairs_bm.csv"
expect_in "$W/err" "$W/bad_mask.csv:3: mask" "bad mask error"
expect_in "$W/err" "32 bits" "bad mask error"
printf 'x,y,z,r,group,mask\n0,0,0,1,-2,1\n' >"$W/bad_group.csv"
expect_rc 1 pairs --spheres "$W/bad_group.csv" --out "$W/pairs_bg.csv"
expect_in "$W/err" "$W/bad_group.csv:2: group: expected an unsigned 32-bit integer" "bad group error"
[[ ! -e "$W/pairs_bm.csv" && ! -e "$W/pairs_bg.csv" ]] || fail "a failed pairs run wrote its output"
pass

# A 4x2 id map of the four spheres: ids 1 1 2 2 / 3 4 0 0 (little-endian uint32), so objects 0
# and 1 cover 2 pixels each, 2 and 3 one each.
u32() { for v in "$@"; do printf "\\x$(printf %02x "$v")\\x00\\x00\\x00"; done; }
u32 1 1 2 2 3 4 0 0 >"$W/ids.u32"
step "pairs --id-map culls by the map's pixels: lambda 2 keeps 0 and 1 -> (0,1)"
expect_rc 0 pairs --spheres "$W/four.xyzr" --id-map "$W/ids.u32" --map-size 4x2 --lambda 2 --out "$W/pairs_id.csv" \
  --stats "$W/stats_id.json"
expect_file_equals "$W/pairs_id.csv" 'i,j\n0,1\n' "pairs from the id map"
expect_in "$W/stats_id.json" '"active": 2' "stats from the id map"
expect_in "$W/stats_id.json" '"mean_pixels": 1.5' "stats from the id map (6 pixels / 4 objects)"
expect_rc 0 pairs --spheres "$W/four.xyzr" --id-map "$W/ids.u32" --map-size 4x2 --lambda 1 --out "$W/pairs_id1.csv"
expect_file_equals "$W/pairs_id1.csv" "$EXPECTED_PAIRS" "pairs from the id map, lambda 1"
# With a camera of 8x4 pixels: 4 screen pixels per map pixel; lambda 5 keeps 0 and 1 (8 each).
printf '{"eye": [0.5, 0, 5], "target": [0.5, 0, 0], "width": 8, "height": 4}\n' >"$W/cam84.json"
expect_rc 0 pairs --spheres "$W/four.xyzr" --id-map "$W/ids.u32" --map-size 4x2 --camera "$W/cam84.json" \
  --lambda 5 --out "$W/pairs_idc.csv" --backend reference
expect_file_equals "$W/pairs_idc.csv" 'i,j\n0,1\n' "pairs from the id map scaled to the camera's screen"
pass

# The four spheres with objects 2 and 3 never culled: with the id map and lambda 2 (which keeps 0
# and 1 alone), all four are active, so the pairs are (0,1) and (2,3).
cat >"$W/four_always.csv" <<'CSV'
x,y,z,r,always_active
0,0,0,0.5,0
1,0,0,0.5,0
100,0,0,1,1
101.5,0,0,1,1
CSV
step "pairs takes an always_active column: flagged objects are never culled"
for be in cpu reference; do
  expect_rc 0 pairs --spheres "$W/four_always.csv" --id-map "$W/ids.u32" --map-size 4x2 --lambda 2 \
    --out "$W/pairs_aa.csv" --stats "$W/stats_aa.json" --backend $be
  expect_file_equals "$W/pairs_aa.csv" 'i,j\n0,1\n2,3\n' "pairs with never-culled objects ($be)"
  expect_in "$W/stats_aa.json" '"active": 4' "every object active ($be)"
done
printf 'x,y,z,r,always_active\n0,0,0,1,1\n0,0,0,1,2\n' >"$W/bad_always.csv"
expect_rc 1 pairs --spheres "$W/bad_always.csv" --out "$W/pairs_ba.csv"
expect_in "$W/err" "$W/bad_always.csv:3: always_active: expected 0 or 1" "bad always_active error"
[[ ! -e "$W/pairs_ba.csv" ]] || fail "a failed pairs run wrote its output"
pass

step "--id-map errors: wrong file size names both sizes, an id beyond N names the pixel, no --map-size"
expect_rc 1 pairs --spheres "$W/four.xyzr" --id-map "$W/ids.u32" --map-size 4x4 --out "$W/pairs_ide.csv"
expect_in "$W/err" "32 bytes" "id map size error"
expect_in "$W/err" "64 bytes" "id map size error"
u32 1 1 2 2 3 4 0 5 >"$W/ids_bad.u32"
expect_rc 1 pairs --spheres "$W/four.xyzr" --id-map "$W/ids_bad.u32" --map-size 4x2 --out "$W/pairs_ide.csv"
expect_in "$W/err" "pixel (3, 1) holds id 5" "id beyond N"
expect_rc 2 pairs --spheres "$W/four.xyzr" --id-map "$W/ids.u32" --out "$W/pairs_ide.csv"
expect_in "$W/err" "--map-size" "--id-map without --map-size"
expect_rc 2 pairs --spheres "$W/four.xyzr" --id-map "$W/ids.u32" --map-size 4x2 --out "$W/ids.u32"
expect_in "$W/err" "refusing to overwrite an input" "--out naming the id map"
[[ ! -e "$W/pairs_ide.csv" ]] || fail "a failed pairs run wrote its output"
pass

step "query --ray: first hit, --all, --max-t (hand-worked on the four spheres)"
expect_rc 0 query --spheres "$W/four.xyzr" --ray -10,0,0,1,0,0
expect_file_equals "$W/out" 'i,t\n0,9.5\n' "first hit"
expect_rc 0 query --spheres "$W/four.xyzr" --ray -10,0,0,1,0,0 --all
expect_file_equals "$W/out" 'i,t\n0,9.5\n1,10.5\n2,109\n3,110.5\n' "every hit"
expect_rc 0 query --spheres "$W/four.xyzr" --ray -10,0,0,2,0,0 --all --max-t 5
expect_file_equals "$W/out" 'i,t\n0,4.75\n' "dir of length 2, max_t 5"
expect_rc 0 query --spheres "$W/four.xyzr" --ray 0,0,0,0,1,0 --all --backend reference
expect_file_equals "$W/out" 'i,t\n0,0\n' "origin inside sphere 0: t = 0"
expect_rc 0 query --spheres "$W/four.xyzr" --ray 0,5,0,0,1,0
expect_file_equals "$W/out" 'i,t\n' "no hit: the header only"
pass

step "query --overlap, --camera culling, --out"
expect_rc 0 query --spheres "$W/four.xyzr" --overlap 0.5,0,0,0
expect_file_equals "$W/out" 'i\n0\n1\n' "a point touching 0 and 1"
expect_rc 0 query --spheres "$W/four.xyzr" --overlap 100.75,0,0,0.1 --out "$W/q.csv"
expect_file_equals "$W/q.csv" 'i\n2\n3\n' "overlap to --out"
# The camera sees 0 and 1 only (lambda 1): 2 and 3 are culled and invisible to queries.
expect_rc 0 query --spheres "$W/four.xyzr" --ray -10,0,0,1,0,0 --all --camera "$W/cam.json" --lambda 1
expect_file_equals "$W/out" 'i,t\n0,9.5\n1,10.5\n' "culled objects are invisible"
# Filters do not apply to queries: sphere 1 (mask 0) is hit.
expect_rc 0 query --spheres "$W/four_filters.csv" --ray -10,0,0,1,0,0 --all --max-t 11
expect_file_equals "$W/out" 'i,t\n0,9.5\n1,10.5\n' "filtered objects are seen"
pass

step "query usage errors exit 2 naming the option"
expect_rc 2 query --spheres "$W/four.xyzr" --ray 1,2,3
expect_in "$W/err" "--ray" "short --ray"
expect_rc 2 query --spheres "$W/four.xyzr" --ray 0,0,0,0,0,0
expect_in "$W/err" "must not be zero" "zero direction"
expect_rc 2 query --spheres "$W/four.xyzr" --ray 0,0,0,1,0,nan
expect_in "$W/err" "--ray" "NaN in --ray"
expect_rc 2 query --spheres "$W/four.xyzr" --ray 0,0,0,1,0,0 --overlap 0,0,0,1
expect_in "$W/err" "one of --ray and --overlap" "both queries"
expect_rc 2 query --spheres "$W/four.xyzr" --overlap 0,0,0,-1
expect_in "$W/err" "--overlap" "negative radius"
expect_rc 2 query --spheres "$W/four.xyzr" --overlap 0,0,0,1 --all
expect_rc 2 query --spheres "$W/four.xyzr" --overlap 0,0,0,1 --out "$W/four.xyzr"
expect_in "$W/err" "refusing to overwrite an input" "--out naming --spheres"
pass

step "run --events and --pairs-dir: events are the set differences of consecutive frames' pairs"
expect_rc 0 run --objects 3000 --frames 5 --no-culling --dt 0.5 --out "$W/ev" --events "$W/ev/events.csv" \
  --pairs-dir "$W/ev_pairs" --quiet
for f in 0 1 2 3 4; do [[ -f "$W/ev_pairs/frame_00000$f.csv" ]] || fail "frame_00000$f.csv missing"; done
[[ "$(ls "$W/ev_pairs" | wc -l)" -eq 5 ]] || fail "--pairs-dir holds other files than the 5 frames"
head -n1 "$W/ev/events.csv" | grep -qx 'frame,i,j,event' || fail "events CSV header"
if command -v python3 >/dev/null 2>&1; then
  cat >"$W/check_events.py" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
def pairs(f):
    return {(int(r["i"]), int(r["j"])) for r in csv.DictReader(open(f"{sys.argv[2]}/frame_{f:06d}.csv"))}
frames = int(sys.argv[3]) if len(sys.argv) > 3 else 5
key = [(int(r["frame"]), 0 if r["event"] == "begin" else 1, int(r["i"]), int(r["j"])) for r in rows]
assert key == sorted(key), "events not sorted by frame, begin before end, i, j"
assert all(r["event"] in ("begin", "end") for r in rows)
before, changes = set(), 0
for f in range(frames):
    now = pairs(f)
    got_b = {(int(r["i"]), int(r["j"])) for r in rows if int(r["frame"]) == f and r["event"] == "begin"}
    got_e = {(int(r["i"]), int(r["j"])) for r in rows if int(r["frame"]) == f and r["event"] == "end"}
    assert got_b == now - before, f"frame {f}: begin"
    assert got_e == before - now, f"frame {f}: end"
    if f:
        changes += len(got_b) + len(got_e)
    before = now
assert len(pairs(0)) > 100 and changes > 0, "a scene with pairs and changes"
PY
  python3 "$W/check_events.py" "$W/ev/events.csv" "$W/ev_pairs" || fail "events differ from the pairs files' set differences"
fi
pass

step "--pairs-dir replaces an earlier run's folder, refuses one with other files, and what lies in it"
expect_rc 0 run --objects 300 --frames 2 --out "$W/ev2" --pairs-dir "$W/ev_pairs" --quiet
[[ "$(ls "$W/ev_pairs" | wc -l)" -eq 2 ]] || fail "--pairs-dir was not replaced by the 2-frame run"
mkdir -p "$W/mine" && echo keep >"$W/mine/notes.txt"
expect_rc 2 run --objects 300 --frames 2 --out "$W/ev3" --pairs-dir "$W/mine" --quiet
expect_in "$W/err" "notes.txt" "a folder with other files"
[[ -f "$W/mine/notes.txt" ]] || fail "the folder with other files was touched"
expect_rc 2 run --objects 300 --frames 2 --out "$W/ev3" --pairs-dir "$W/ev3" --quiet
expect_in "$W/err" "lies in --pairs-dir" "outputs inside --pairs-dir"
expect_rc 2 run --objects 300 --frames 2 --out "$W/ev3" --events "$W/cam.json" --camera "$W/cam.json" --quiet
expect_in "$W/err" "refusing to overwrite an input" "--events naming the camera"
pass

step "a failed run writes neither --events nor --pairs-dir"
expect_rc 1 run --objects 3000 --frames 3 --no-culling --max-pair-memory 8 --out "$W/ev4" \
  --events "$W/ev4_events.csv" --pairs-dir "$W/ev4_pairs" --quiet
[[ ! -e "$W/ev4_events.csv" && ! -e "$W/ev4_pairs" ]] || fail "a failed run left --events or --pairs-dir"
[[ -z "$(ls -A "$W" | grep '^\.ev4' || true)" ]] || fail "a failed run left a temporary file or folder"
pass

step "--help of the new options teaches"
expect_rc 0 query --help
expect_in "$W/out" "--ray" "query --help"
expect_in "$W/out" "--overlap" "query --help"
expect_rc 0 run --help
expect_in "$W/out" "--events" "run --help"
expect_in "$W/out" "--pairs-dir" "run --help"
expect_rc 0 pairs --help
expect_in "$W/out" "--id-map" "pairs --help"
expect_in "$W/out" "group" "pairs --help"
pass

# ----------------------------------------------------------------------------------------------
# Boxes and the static set: pairs and queries from box files, --static (numbered N + k), and
# run --shape box --static K. The oracles are brute force written here in awk, on coordinates in
# quarters, which float and awk's doubles hold exactly, so that touching counts the same in both.

# 300 boxes on a grid of quarters, sides 0 to 3: many touch exactly.
awk 'BEGIN { srand(11); print "minx,miny,minz,maxx,maxy,maxz"
  for (k = 0; k < 300; ++k) {
    for (a = 0; a < 3; ++a) { lo[a] = int(rand() * 80) / 4; hi[a] = lo[a] + int(rand() * 13) / 4 }
    printf "%g,%g,%g,%g,%g,%g\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2] } }' >"$W/boxes.csv"
# 40 static boxes (walls and blocks) with the same grid.
awk 'BEGIN { srand(12); print "minx,miny,minz,maxx,maxy,maxz"
  for (k = 0; k < 40; ++k) {
    for (a = 0; a < 3; ++a) { lo[a] = int(rand() * 80) / 4; hi[a] = lo[a] + int(rand() * 25) / 4 }
    printf "%g,%g,%g,%g,%g,%g\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2] } }' >"$W/walls.csv"
# box_pairs MOVING [STATIC]: the pairs CSV by brute force: closed boxes overlap when
# min_i <= max_j and min_j <= max_i on every axis; static object k is N + k; no static-static pairs.
box_pairs() {
  awk -F, 'BEGIN { n = m = 0 } FNR == 1 { ++file; next }
    { for (a = 1; a <= 6; ++a) v[file, file == 1 ? n : m, a] = $a + 0; if (file == 1) ++n; else ++m }
    function meet(f, i, g, j,   a) {
      for (a = 1; a <= 3; ++a) if (v[f, i, a] > v[g, j, a + 3] || v[g, j, a] > v[f, i, a + 3]) return 0
      return 1 }
    END { print "i,j"
      for (i = 0; i < n; ++i) {
        for (j = i + 1; j < n; ++j) if (meet(1, i, 1, j)) print i "," j
        for (k = 0; k < m; ++k) if (meet(1, i, 2, k)) print i "," n + k } }' "$@"
}
# sphere_pairs MOVING [STATIC]: the same for x,y,z,r CSVs: |c_i - c_j| <= r_i + r_j, squared.
sphere_pairs() {
  awk -F, 'BEGIN { n = m = 0 } FNR == 1 { ++file; next }
    { for (a = 1; a <= 4; ++a) v[file, file == 1 ? n : m, a] = $a + 0; if (file == 1) ++n; else ++m }
    function meet(f, i, g, j,   dx, dy, dz, s) {
      dx = v[f, i, 1] - v[g, j, 1]; dy = v[f, i, 2] - v[g, j, 2]; dz = v[f, i, 3] - v[g, j, 3]
      s = v[f, i, 4] + v[g, j, 4]; return dx * dx + dy * dy + dz * dz <= s * s }
    END { print "i,j"
      for (i = 0; i < n; ++i) {
        for (j = i + 1; j < n; ++j) if (meet(1, i, 1, j)) print i "," j
        for (k = 0; k < m; ++k) if (meet(1, i, 2, k)) print i "," n + k } }' "$@"
}
expect_sorted_pairs() {  # expect_sorted_pairs FILE WHAT: header i,j, then i < j, sorted by (i, j), unique
  head -n1 "$1" | grep -qx 'i,j' || fail "$2: no header i,j"
  awk -F, 'NR > 1 { if (!($1 < $2)) exit 1; if (NR > 2 && ($1 < pi || ($1 == pi && $2 <= pj))) exit 1; pi = $1; pj = $2 }' \
    "$1" || fail "$2: pairs not sorted by (i, j) with i < j"
}

step "pairs --boxes equals the brute force, on cpu and reference, for every Morton width"
box_pairs "$W/boxes.csv" >"$W/boxes_expected.csv"
[[ "$(wc -l <"$W/boxes_expected.csv")" -gt 100 ]] || fail "the box fixture has too few pairs to mean much"
for be in cpu reference; do
  for bits in adaptive 16 64; do
    expect_rc 0 pairs --boxes "$W/boxes.csv" --out "$W/boxes_$be.csv" --backend $be --bits $bits
    cmp -s "$W/boxes_expected.csv" "$W/boxes_$be.csv" ||
      { diff "$W/boxes_expected.csv" "$W/boxes_$be.csv" | head >&2; fail "box pairs ($be, --bits $bits) differ from the brute force"; }
  done
done
expect_in "$W/out" "300 objects, 300 active" "pairs --boxes summary"
pass

step "pairs --boxes --static: static object k is N + k, sorted, equal to the brute force"
box_pairs "$W/boxes.csv" "$W/walls.csv" >"$W/walls_expected.csv"
grep -qE '^[0-9]+,(3[0-9][0-9])$' "$W/walls_expected.csv" || fail "the fixture has no pair with a static box"
for be in cpu reference; do
  expect_rc 0 pairs --boxes "$W/boxes.csv" --static "$W/walls.csv" --out "$W/walls_$be.csv" --stats "$W/walls_$be.json" \
    --backend $be
  expect_sorted_pairs "$W/walls_$be.csv" "pairs with a static set ($be)"
  cmp -s "$W/walls_expected.csv" "$W/walls_$be.csv" ||
    { diff "$W/walls_expected.csv" "$W/walls_$be.csv" | head >&2; fail "static-set pairs ($be) differ from the brute force"; }
  expect_in "$W/out" "300 objects + 40 static" "pairs summary with --static ($be)"
  expect_in "$W/walls_$be.json" '"static_objects": 40' "stats JSON with --static ($be)"
done
# The hash printed is the written CSV's: --validate-hash takes it.
HASH_STATIC="$(grep -oE 'hash [0-9a-f]{16}' "$W/out" | cut -d' ' -f2)"
expect_rc 0 pairs --boxes "$W/boxes.csv" --static "$W/walls.csv" --out "$W/walls_v.csv" --validate-hash "$HASH_STATIC"
pass

step "pairs --spheres --static: the same numbering for spheres (cloud on quarters)"
awk 'BEGIN { srand(21); print "x,y,z,r"; for (k = 0; k < 250; ++k)
  printf "%g,%g,%g,%g\n", int(rand() * 80) / 4, int(rand() * 80) / 4, int(rand() * 8) / 4, int(rand() * 4 + 1) / 4 }' \
  >"$W/balls.csv"
awk 'BEGIN { srand(22); print "x,y,z,r"; for (k = 0; k < 30; ++k)
  printf "%g,%g,%g,%g\n", int(rand() * 80) / 4, int(rand() * 80) / 4, 0, int(rand() * 8 + 4) / 4 }' >"$W/rocks.csv"
sphere_pairs "$W/balls.csv" "$W/rocks.csv" >"$W/rocks_expected.csv"
grep -qE ',(2[5-7][0-9])$' "$W/rocks_expected.csv" || fail "the fixture has no pair with a static sphere"
for be in cpu reference; do
  expect_rc 0 pairs --spheres "$W/balls.csv" --static "$W/rocks.csv" --out "$W/rocks_$be.csv" --backend $be
  cmp -s "$W/rocks_expected.csv" "$W/rocks_$be.csv" ||
    { diff "$W/rocks_expected.csv" "$W/rocks_$be.csv" | head >&2; fail "sphere static-set pairs ($be) differ"; }
done
# An XYZR static file with XYZR spheres.
tail -n +2 "$W/rocks.csv" | tr ',' ' ' >"$W/rocks.xyzr"
expect_rc 0 pairs --spheres "$W/balls.csv" --static "$W/rocks.xyzr" --out "$W/rocks_xyzr.csv"
cmp -s "$W/rocks_expected.csv" "$W/rocks_xyzr.csv" || fail "an XYZR static file gives other pairs"
pass

# Four boxes: 0 and 1 share a face, 2 and 3 overlap; two static boxes: a floor under 0 and 1
# (touching them from below) and a block touching 3's corner. With filters: the block (group 4)
# accepts group 2 only, and box 3 is group 2; box 1 (mask 0) collides with nothing.
cat >"$W/four_boxes.csv" <<'CSV'
minx,miny,minz,maxx,maxy,maxz,group,mask
0,0,0,1,1,1,1,0xFFFFFFFF
1,0,0,2,1,1,2,0
5,5,5,6,6,6,1,0xFFFFFFFF
5.5,5.5,5.5,7,7,7,2,0xFFFFFFFF
CSV
cat >"$W/two_static.csv" <<'CSV'
minx,miny,minz,maxx,maxy,maxz,group,mask
-10,-1,-10,10,0,10,1,0xFFFFFFFF
7,7,7,8,8,8,4,2
CSV
step "boxes with filters and a static set: hand-worked pairs, numbers 4 and 5 for the static boxes"
expect_rc 0 pairs --boxes "$W/four_boxes.csv" --out "$W/fb.csv"
expect_file_equals "$W/fb.csv" 'i,j\n2,3\n' "filtered box pairs"
for be in cpu reference; do
  expect_rc 0 pairs --boxes "$W/four_boxes.csv" --static "$W/two_static.csv" --out "$W/fbs.csv" --backend $be
  expect_file_equals "$W/fbs.csv" 'i,j\n0,4\n2,3\n3,5\n' "filtered box pairs with a static set ($be)"
done
pass

step "query --boxes --static: rays and overlaps see static objects as N + k"
expect_rc 0 query --boxes "$W/four_boxes.csv" --static "$W/two_static.csv" --ray 0.5,10,0.5,0,-1,0 --all
expect_file_equals "$W/out" 'i,t\n0,9\n4,10\n' "a ray down through box 0 onto the floor"
expect_rc 0 query --boxes "$W/four_boxes.csv" --static "$W/two_static.csv" --ray 0.5,10,0.5,0,-1,0 --backend reference
expect_file_equals "$W/out" 'i,t\n0,9\n' "the first hit"
expect_rc 0 query --boxes "$W/four_boxes.csv" --static "$W/two_static.csv" --overlap-box 7,7,7,7,7,7
expect_file_equals "$W/out" 'i\n3\n5\n' "a point on 3's corner and the block's"
expect_rc 0 query --boxes "$W/four_boxes.csv" --static "$W/two_static.csv" --overlap 1,1,0.5,0
expect_file_equals "$W/out" 'i\n0\n1\n' "a point on the shared edge of 0 and 1"
expect_rc 0 query --spheres "$W/four.xyzr" --static "$W/rocks.xyzr" --overlap 100.75,0,0,0.1
expect_file_equals "$W/out" 'i\n2\n3\n' "spheres with a static set far away"
expect_rc 2 query --boxes "$W/four_boxes.csv" --overlap-box 1,0,0,0,1,1
expect_in "$W/err" "--overlap-box: minx" "--overlap-box with min > max"
expect_rc 2 query --boxes "$W/four_boxes.csv" --overlap-box 1,0,0
expect_in "$W/err" "--overlap-box" "short --overlap-box"
pass

step "--spheres and --boxes: exactly one; a --static file of the other kind exits 1 naming file:line"
expect_rc 2 pairs --spheres "$W/four.xyzr" --boxes "$W/four_boxes.csv" --out "$W/both.csv"
expect_in "$W/err" "one of --spheres and --boxes" "both kinds"
expect_rc 2 query --ray 0,0,0,1,0,0
expect_in "$W/err" "one of --spheres and --boxes" "query without objects"
expect_rc 1 pairs --boxes "$W/four_boxes.csv" --static "$W/rocks.csv" --out "$W/mixed.csv"
expect_in "$W/err" "$W/rocks.csv:1: a sphere file" "sphere static file with boxes"
expect_in "$W/err" "--static must hold boxes too" "sphere static file with boxes"
expect_rc 1 pairs --boxes "$W/four_boxes.csv" --static "$W/rocks.xyzr" --out "$W/mixed.csv"
expect_in "$W/err" "$W/rocks.xyzr:1: a sphere file (XYZR" "XYZR static file with boxes"
expect_rc 1 query --spheres "$W/four.xyzr" --static "$W/two_static.csv" --overlap 0,0,0,1
expect_in "$W/err" "$W/two_static.csv:1: a box file" "box static file with spheres"
expect_in "$W/err" "--static must hold spheres too" "box static file with spheres"
expect_rc 1 pairs --spheres "$W/four_boxes.csv" --out "$W/mixed.csv"
expect_in "$W/err" "$W/four_boxes.csv:1: expected the header \`x,y,z,r\`" "a box file as --spheres"
expect_in "$W/err" "a box file, where spheres were expected" "a box file as --spheres"
[[ ! -e "$W/mixed.csv" && ! -e "$W/both.csv" ]] || fail "a refused pairs run wrote its output"
expect_rc 2 pairs --boxes "$W/four_boxes.csv" --static "$W/two_static.csv" --out "$W/two_static.csv"
expect_in "$W/err" "refusing to overwrite an input" "--out naming --static"
pass

step "--backend gl with boxes and a static set: the brute force's pairs"
set +e
"$VISCD" pairs --boxes "$W/boxes.csv" --static "$W/walls.csv" --out "$W/walls_gl.csv" --backend gl >"$W/out" 2>"$W/err"
rc=$?
set -e
if [[ "$rc" -eq 0 ]]; then
  cmp -s "$W/walls_expected.csv" "$W/walls_gl.csv" || fail "gl box pairs differ from the brute force"
elif grep -q "does not take" "$W/err"; then
  fail "gl refused boxes or a static set: $(head -n 1 "$W/err")"
else
  echo "    skipped: no gl backend here ($(head -n 1 "$W/err"))"
fi
pass

step "run --shape box --static 200: summary, frames.csv and every frame's pairs number static k as N + k"
# Fixed bits and no culling: no visibility map but the last frame's screenshot, kept small for the
# reference backend, which ray-casts every pixel against every object.
expect_rc 0 run --objects 2000 --frames 3 --shape box --static 200 --no-culling --bits 32 --size 64x36 --dt 0.5 \
  --out "$W/runbox" --pairs-dir "$W/runbox_pairs" --events "$W/runbox/events.csv" --backend cpu
expect_in "$W/out" "2000 boxes (ring scene, seed 1) + 200 static" "run header"
expect_in "$W/out" ", 200 static," "run's last frame"
head -n1 "$W/runbox/frames.csv" | grep -q '^frame,time_s,objects,static_objects,' || fail "frames.csv has no static_objects"
awk -F, 'NR > 1 && ($3 != 2000 || $4 != 200) { exit 1 }' "$W/runbox/frames.csv" || fail "frames.csv counts"
if command -v python3 >/dev/null 2>&1; then
  python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); assert d["shape"]=="box" and d["static_objects"]==200 and d["last_frame"]["static_objects"]==200, d' \
    "$W/runbox/summary.json" || fail "summary.json lacks the shape or the static count"
fi
for f in 0 1 2; do
  expect_sorted_pairs "$W/runbox_pairs/frame_00000$f.csv" "run frame $f"
  awk -F, 'NR > 1 && ($2 >= 2200 || $1 >= 2000) { exit 1 } NR > 1 && $2 >= 2000 { s = 1 } END { exit !s }' \
    "$W/runbox_pairs/frame_00000$f.csv" || fail "frame $f: no pair with a static object, or one numbered beyond N + K"
done
if command -v python3 >/dev/null 2>&1; then
  python3 "$W/check_events.py" "$W/runbox/events.csv" "$W/runbox_pairs" 3 || fail "events differ from the pairs files"
fi
# The same frames by the reference backend (brute force): the same pairs.
expect_rc 0 run --objects 2000 --frames 3 --shape box --static 200 --no-culling --bits 32 --size 64x36 --dt 0.5 \
  --out "$W/runbox_ref" --pairs-dir "$W/runbox_ref_pairs" --backend reference --quiet
for f in 0 1 2; do
  cmp -s "$W/runbox_pairs/frame_00000$f.csv" "$W/runbox_ref_pairs/frame_00000$f.csv" ||
    fail "run --shape box --static: cpu and reference differ in frame $f"
done
pass

step "run --static with spheres, with culling: a screenshot; bad --shape and --static are usage errors"
expect_rc 0 run --objects 2000 --frames 2 --static 100 --out "$W/runrocks" --quiet
[[ -s "$W/runrocks/screenshot.png" ]] || fail "run --static wrote no screenshot"
expect_rc 2 run --objects 100 --frames 1 --shape cube --out "$W/runbad"
expect_in "$W/err" "--shape: unknown shape 'cube': expected sphere or box" "--shape cube"
expect_rc 2 run --objects 100 --frames 1 --static -1 --out "$W/runbad"
expect_in "$W/err" "--static" "--static -1"
pass

step "--help teaches --boxes, --static, --overlap-box and --shape"
expect_rc 0 pairs --help
for word in --boxes --static "minx,miny,minz,maxx,maxy,maxz" "N + k"; do expect_in "$W/out" "$word" "pairs --help"; done
expect_rc 0 query --help
for word in --boxes --static --overlap-box; do expect_in "$W/out" "$word" "query --help"; done
expect_rc 0 run --help
for word in --shape --static "N + k"; do expect_in "$W/out" "$word" "run --help"; done
pass

# ----------------------------------------------------------------------------------------------
# Which backend runs: --backend auto says which it picked and why; a gl that cannot start is an
# error outside the viewer. __EGL_VENDOR_LIBRARY_FILENAMES naming no file leaves libglvnd with no
# EGL driver, which stands in for a machine without OpenGL.
NO_EGL=/nonexistent/viscd-no-egl-vendor.json

step "--backend auto says on stderr which backend it picked and why, and runs it"
expect_rc 0 pairs --spheres "$W/four.xyzr" --out "$W/pairs_auto.csv" --backend auto
expect_file_equals "$W/pairs_auto.csv" "$EXPECTED_PAIRS" "pairs with --backend auto"
expect_in "$W/err" "viscd: backend auto -> " "the auto message"
grep -qE "backend auto -> (gl: hardware OpenGL: |cpu: no OpenGL 4.5 context \(|cpu: the only OpenGL is a software renderer, )" \
  "$W/err" || { show pairs auto; fail "the auto message names neither gl on hardware nor why cpu"; }
pass

step "without OpenGL: auto -> cpu naming the reason; --backend gl fails (exit 1) naming it; --quiet is quiet"
__EGL_VENDOR_LIBRARY_FILENAMES=$NO_EGL run pairs --spheres "$W/four.xyzr" --out "$W/pairs_noegl.csv" --backend auto
if [[ "$rc" -eq 0 ]] && grep -q "backend auto -> cpu: no OpenGL 4.5 context (" "$W/err"; then
  expect_file_equals "$W/pairs_noegl.csv" "$EXPECTED_PAIRS" "pairs after auto -> cpu"
  REASON="$(sed -n 's/.*no OpenGL 4.5 context (\(.*\))$/\1/p' "$W/err" | head -n 1)"
  [[ -n "$REASON" ]] || { show pairs auto; fail "the auto message gives no reason"; }
  __EGL_VENDOR_LIBRARY_FILENAMES=$NO_EGL run pairs --spheres "$W/four.xyzr" --out "$W/pairs_noegl_gl.csv" --backend gl
  [[ "$rc" -eq 1 ]] || { show pairs gl; fail "--backend gl without OpenGL exited $rc, expected 1"; }
  expect_in "$W/err" "viscd: error: $REASON" "--backend gl without OpenGL"
  [[ ! -e "$W/pairs_noegl_gl.csv" ]] || fail "a pairs run whose backend did not start wrote its output"
  __EGL_VENDOR_LIBRARY_FILENAMES=$NO_EGL run run --objects 200 --frames 1 --out "$W/run_noegl" --quiet
  [[ "$rc" -eq 0 && ! -s "$W/err" && ! -s "$W/out" ]] || { show run --quiet; fail "run --quiet (auto) was not quiet"; }
  pass
else
  echo "    skipped: the EGL vendor override did not take here ($(head -n 1 "$W/err"))"
fi

# ----------------------------------------------------------------------------------------------
# The cpu backend's kernels: --simd and --keep-order (run and pairs) over VISCD_SIMD and
# VISCD_KEEP_ORDER.
awk 'BEGIN { srand(7); print "x,y,z,r"; for (k = 0; k < 3000; ++k) printf "%.4f,%.4f,%.4f,%.3f\n", 40 * rand(), 40 * rand(), 4 * rand(), 0.3 + 0.5 * rand() }' \
  >"$W/cloud.csv"
step "--simd best, sse2 and scalar give the same pairs; a bad value is a usage error naming --simd"
expect_rc 0 pairs --spheres "$W/cloud.csv" --out "$W/pairs_simd_default.csv"
[[ "$(wc -l <"$W/pairs_simd_default.csv")" -gt 100 ]] || fail "the cloud has too few pairs to compare kernels"
for simd in best sse2 scalar; do
  expect_rc 0 pairs --spheres "$W/cloud.csv" --out "$W/pairs_simd_$simd.csv" --simd "$simd"
  cmp -s "$W/pairs_simd_default.csv" "$W/pairs_simd_$simd.csv" || fail "--simd $simd gives other pairs"
done
VISCD_SIMD=sse2 expect_rc 0 pairs --spheres "$W/cloud.csv" --out "$W/pairs_simd_env.csv" --simd scalar
cmp -s "$W/pairs_simd_default.csv" "$W/pairs_simd_env.csv" || fail "--simd scalar over VISCD_SIMD gives other pairs"
expect_rc 2 pairs --spheres "$W/cloud.csv" --out "$W/pairs_simd_bad.csv" --simd avx
expect_in "$W/err" "--simd: expected best, sse2 or scalar, got 'avx'" "--simd avx"
expect_rc 2 run --objects 100 --frames 1 --out "$W/run_simd_bad" --simd 4
expect_in "$W/err" "--simd" "run --simd 4"
pass

# With every object active, a frame that keeps the order skips the sort: its sort_ms is 0.
sort_zeros() {  # sort_zeros FRAMES_CSV: how many frames after the first have sort_ms 0
  awk -F, 'NR == 1 { for (k = 1; k <= NF; ++k) if ($k == "sort_ms") c = k; next }
           NR > 2 && $c == 0 { ++n } END { print n + 0 }' "$1"
}
step "--keep-order off sorts every frame, on keeps the order, each over VISCD_KEEP_ORDER; bad values exit 2"
expect_rc 0 run --objects 3000 --frames 6 --no-culling --out "$W/keep_off" --keep-order off --quiet
[[ "$(sort_zeros "$W/keep_off/frames.csv")" -eq 0 ]] || fail "--keep-order off skipped a sort"
VISCD_KEEP_ORDER=1 expect_rc 0 run --objects 3000 --frames 6 --no-culling --out "$W/keep_off_env" --keep-order off --quiet
[[ "$(sort_zeros "$W/keep_off_env/frames.csv")" -eq 0 ]] || fail "--keep-order off did not override VISCD_KEEP_ORDER=1"
VISCD_KEEP_ORDER=0 expect_rc 0 run --objects 3000 --frames 6 --no-culling --out "$W/keep_on_env" --keep-order on --quiet
[[ "$(sort_zeros "$W/keep_on_env/frames.csv")" -gt 0 ]] || fail "--keep-order on did not override VISCD_KEEP_ORDER=0"
expect_rc 0 pairs --spheres "$W/cloud.csv" --out "$W/pairs_keep.csv" --keep-order off
cmp -s "$W/pairs_simd_default.csv" "$W/pairs_keep.csv" || fail "--keep-order off gives other pairs"
expect_rc 2 pairs --spheres "$W/cloud.csv" --out "$W/pairs_keep_bad.csv" --keep-order maybe
expect_in "$W/err" "--keep-order: expected on or off, got 'maybe'" "--keep-order maybe"
pass

step "--follow-change and --rest-margin give the same pairs; bad values, as option or VISCD_FOLLOW_CHANGE, exit 2"
expect_rc 0 pairs --spheres "$W/cloud.csv" --out "$W/pairs_follow.csv" --follow-change off --rest-margin 0.5
cmp -s "$W/pairs_simd_default.csv" "$W/pairs_follow.csv" || fail "--follow-change off --rest-margin 0.5 gives other pairs"
expect_rc 2 pairs --spheres "$W/cloud.csv" --out "$W/pairs_follow_bad.csv" --follow-change maybe
expect_in "$W/err" "--follow-change: expected on or off, got 'maybe'" "--follow-change maybe"
expect_rc 2 pairs --spheres "$W/cloud.csv" --out "$W/pairs_margin_bad.csv" --rest-margin -1
expect_in "$W/err" "--rest-margin -1.000000: expected a finite distance >= 0" "--rest-margin -1"
VISCD_FOLLOW_CHANGE=2 expect_rc 2 pairs --spheres "$W/cloud.csv" --out "$W/pairs_env_bad.csv"
expect_in "$W/err" "VISCD_FOLLOW_CHANGE=2: expected 1 or 0" "VISCD_FOLLOW_CHANGE=2"
pass

step "run and pairs --help teach --simd, --keep-order, --follow-change and --rest-margin"
for cmd in run pairs; do
  expect_rc 0 "$cmd" --help
  expect_in "$W/out" "--simd" "$cmd --help"
  expect_in "$W/out" "--keep-order" "$cmd --help"
  expect_in "$W/out" "--follow-change" "$cmd --help"
  expect_in "$W/out" "--rest-margin" "$cmd --help"
done
pass

# Kept last so that a failure here does not hide the checks above.
step "run --quiet prints nothing (its help: 'print nothing but errors')"
expect_rc 0 run --objects 100 --frames 2 --out "$W/run7" --quiet
[[ ! -s "$W/out" ]] || { show run --quiet; fail "run --quiet wrote to stdout"; }
[[ ! -s "$W/err" ]] || { show run --quiet; fail "run --quiet wrote to stderr although nothing failed"; }
pass

echo "cli_test.sh: all $checks checks passed"
