#!/usr/bin/env bash
# Command-line tests of the `viscd` tool: exit codes, outputs and messages of `pairs` and `run`.
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

step "viscd pairs --help mentions --spheres"
expect_rc 0 pairs --help
expect_in "$W/out" "--spheres" "pairs --help"
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
fi
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

step "run --frames 0 is a usage error (exit 2)"
expect_rc 2 run --frames 0 --objects 100 --out "$W/run6"
expect_in "$W/err" "--frames" "--frames 0 error"
pass

# Kept last so that a failure here does not hide the checks above.
step "run --quiet prints nothing (its help: 'print nothing but errors')"
expect_rc 0 run --objects 100 --frames 2 --out "$W/run7" --quiet
[[ ! -s "$W/out" ]] || { show run --quiet; fail "run --quiet wrote to stdout"; }
[[ ! -s "$W/err" ]] || { show run --quiet; fail "run --quiet wrote to stderr although nothing failed"; }
pass

echo "cli_test.sh: all $checks checks passed"
