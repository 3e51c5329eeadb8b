#!/usr/bin/env bash
# Hostile input to the `viscd` tool: out-of-range numbers, outputs that name inputs, full disks,
# too little memory, binary bytes in files, bad option values. Each check failed (a crash, an
# abort, a destroyed file or a silent success) before the tool handled that case.
# Usage: VISCD=/path/to/viscd [VISCD_SANITIZED=1] bash tests/apps/hostile_test.sh WORKDIR
# VISCD_SANITIZED=1 (an ASan build) skips the checks that limit the address space: ASan reserves
# terabytes of it at start-up.
set -euo pipefail

source "$(dirname "$0")/cli_lib.sh"

expect_no_control_bytes() {  # expect_no_control_bytes FILE WHAT: no byte below 0x20 but newline, no DEL
  if LC_ALL=C grep -q '[^[:print:][:space:]]' "$1" || LC_ALL=C grep -qP '[\x00-\x08\x0b-\x1f\x7f]' "$1"; then
    od -c "$1" | head -n 5 >&2
    fail "$2: raw control characters in $(basename "$1")"
  fi
}

cat >"$W/four.xyzr" <<'EOF'
0 0 0 0.5
1 0 0 0.5
100 0 0 1
101.5 0 0 1
EOF
EXPECTED_PAIRS='i,j\n0,1\n2,3\n'
# A row of 2000 touching spheres: 1999 pairs, a pairs CSV of about 20 KB.
awk 'BEGIN { for (k = 0; k < 2000; ++k) printf "%d 0 0 0.5\n", k }' >"$W/row.xyzr"
# 3000 spheres at one point: 4 498 500 pairs (36 MB of pairs).
awk 'BEGIN { for (k = 0; k < 3000; ++k) print "0 0 0 1" }' >"$W/same3000.xyzr"

# ----------------------------------------------------------------------------------------------
step "a camera number beyond double's range (far 1e400) is an error naming the file, not an abort"
echo '{"eye": [0, 0, 10], "far": 1e400}' >"$W/far.json"
expect_rc 1 pairs --spheres "$W/four.xyzr" --camera "$W/far.json" --out "$W/p_far.csv"
expect_in "$W/err" "far.json" "far 1e400"
expect_in "$W/err" "invalid JSON" "far 1e400"
pass

step "a camera eye beyond 1e18 (which made the visibility map 500x slower) is an error"
echo '{"eye": [0, 1e30, 1e30], "target": [0, 0, 0], "far": 1e18}' >"$W/eye.json"
expect_rc 1 pairs --spheres "$W/four.xyzr" --camera "$W/eye.json" --out "$W/p_eye.csv"
expect_in "$W/err" '"eye"' "eye 1e30"
expect_in "$W/err" "1e18" "eye 1e30"
pass

step "a camera JSON error gives file:line:column and the whole reason"
printf '{"eye": [1, 2,\n  3x]}\n' >"$W/syntax.json"
expect_rc 1 pairs --spheres "$W/four.xyzr" --camera "$W/syntax.json" --out "$W/p_syntax.csv"
expect_in "$W/err" "syntax.json:2:" "JSON syntax error position"
expect_in "$W/err" "syntax error while parsing" "JSON syntax error reason"
pass

step "--threads beyond the machine is clamped (no libgomp abort); negative or absurd is a usage error"
echo '{"eye": [0.5, 0, 5], "target": [0.5, 0, 0], "width": 64, "height": 36}' >"$W/cam.json"
expect_rc 0 pairs --spheres "$W/four.xyzr" --camera "$W/cam.json" --lambda 1 --threads 60000 --out "$W/p_thr.csv"
[[ ! -s "$W/err" ]] || { show; fail "--threads 60000 printed to stderr"; }
expect_rc 2 pairs --spheres "$W/four.xyzr" --camera "$W/cam.json" --threads 100000 --out "$W/p_thr2.csv"
expect_in "$W/err" "--threads" "--threads 100000"
expect_rc 2 pairs --spheres "$W/four.xyzr" --threads -1 --out "$W/p_thr3.csv"
expect_in "$W/err" "--threads" "--threads -1"
pass

# ----------------------------------------------------------------------------------------------
step "--max-pair-memory caps a frame's pairs with a clear error (exit 1); 0 means no cap"
expect_rc 1 pairs --spheres "$W/same3000.xyzr" --out "$W/p_cap.csv" --max-pair-memory 1M
expect_in "$W/err" "pair memory cap" "--max-pair-memory 1M"
expect_in "$W/err" "--max-pair-memory" "--max-pair-memory 1M"
[[ ! -e "$W/p_cap.csv" ]] || fail "a failed frame left a pairs CSV behind"
expect_rc 0 pairs --spheres "$W/same3000.xyzr" --out "$W/p_nocap.csv" --max-pair-memory 0
expect_in "$W/out" "4498500 pairs" "--max-pair-memory 0"
expect_rc 2 pairs --spheres "$W/four.xyzr" --out "$W/p_capbad.csv" --max-pair-memory lots
expect_in "$W/err" "--max-pair-memory" "--max-pair-memory lots"
pass

step "--help prints the default pair memory cap"
expect_rc 0 pairs --help
expect_in "$W/out" "--max-pair-memory" "pairs --help"
expect_in "$W/out" "memory available" "pairs --help"
pass

if [[ "${VISCD_SANITIZED:-0}" != 1 ]]; then
  step "20 000 coincident spheres (200 M pairs) under a 4 GB address-space limit: a clear error, no abort"
  awk 'BEGIN { print "x,y,z,r"; for (k = 0; k < 20000; ++k) print "0,0,0,1" }' >"$W/same20000.csv"
  set +e
  (ulimit -v 4000000 && exec "$VISCD" pairs --spheres "$W/same20000.csv" --out "$W/p_big.csv") >"$W/out" 2>"$W/err"
  rc=$?
  set -e
  [[ "$rc" -eq 1 ]] || { show pairs same20000; fail "exit $rc, expected 1"; }
  expect_in "$W/err" "pair memory cap" "200 M pairs under 4 GB"
  pass

  step "the same with no cap runs out of memory: a clear error naming the frame, no abort"
  set +e
  (ulimit -v 4000000 && exec "$VISCD" pairs --spheres "$W/same20000.csv" --out "$W/p_big.csv" --max-pair-memory 0) \
    >"$W/out" 2>"$W/err"
  rc=$?
  set -e
  [[ "$rc" -eq 1 ]] || { show pairs same20000 nocap; fail "exit $rc, expected 1"; }
  expect_in "$W/err" "out of memory" "no cap under 4 GB"
  expect_in "$W/err" "20000 objects" "no cap under 4 GB"
  pass
fi

step "run --objects 4294967295 and --map-size 65536x65536 are usage errors, at once"
expect_rc 2 run --objects 4294967295 --frames 1 --out "$W/r1"
expect_in "$W/err" "--objects" "--objects 4294967295"
expect_rc 2 run --map-size 65536x65536 --frames 1 --out "$W/r2"
expect_in "$W/err" "--map-size" "--map-size 65536x65536"
expect_rc 2 run --size 20000x20000 --frames 1 --out "$W/r3"
expect_in "$W/err" "--size" "--size 20000x20000"
pass

# ----------------------------------------------------------------------------------------------
step "--out or --stats naming the input (also through a symbolic or hard link) is refused; the input is kept"
cp "$W/four.xyzr" "$W/keep.xyzr"
ln -s "$W/keep.xyzr" "$W/sym.csv"
ln "$W/keep.xyzr" "$W/hard.csv"
for out in "$W/keep.xyzr" "$W/sym.csv" "$W/hard.csv"; do
  expect_rc 2 pairs --spheres "$W/keep.xyzr" --out "$out"
  expect_in "$W/err" "refusing to overwrite an input" "--out $out"
  cmp -s "$W/keep.xyzr" "$W/four.xyzr" || fail "the input was changed by --out $out"
done
expect_rc 2 pairs --spheres "$W/keep.xyzr" --out "$W/p_ok.csv" --stats "$W/keep.xyzr"
expect_in "$W/err" "--stats" "--stats = input"
cmp -s "$W/keep.xyzr" "$W/four.xyzr" || fail "the input was changed by --stats"
[[ ! -e "$W/p_ok.csv" ]] || fail "a refused command wrote --out"
expect_rc 2 pairs --spheres "$W/keep.xyzr" --camera "$W/cam.json" --out "$W/cam.json"
expect_in "$W/err" "--camera" "--out = camera"
expect_rc 2 pairs --spheres "$W/keep.xyzr" --out "$W/same.out" --stats "$W/same.out"
expect_in "$W/err" "name the same file" "--out = --stats"
expect_rc 2 pairs --spheres "$W/keep.xyzr" --out "$W"
expect_in "$W/err" "is a folder" "--out = a folder"
pass

step "on a full disk the previous output survives whole and no partial or temporary file is left"
expect_rc 0 pairs --spheres "$W/four.xyzr" --out "$W/full/pairs.csv"
expect_file_equals "$W/full/pairs.csv" "$EXPECTED_PAIRS" "previous output"
set +e
# RLIMIT_FSIZE of 4 KiB stands in for a full disk: a write past it fails with EFBIG.
(trap '' XFSZ && ulimit -f 4 && exec "$VISCD" pairs --spheres "$W/row.xyzr" --out "$W/full/pairs.csv") \
  >"$W/out" 2>"$W/err"
rc=$?
set -e
[[ "$rc" -eq 1 ]] || { show pairs row; fail "a write past the file-size limit exited $rc, expected 1"; }
expect_in "$W/err" "write failed" "full disk"
expect_file_equals "$W/full/pairs.csv" "$EXPECTED_PAIRS" "the previous output after a failed write"
LEFT="$(find "$W/full" -type f ! -name pairs.csv)"
[[ -z "$LEFT" ]] || fail "files left behind after a failed write: $LEFT"
pass

step "when --stats cannot be written, the pairs CSV is not written either"
printf 'old\n' >"$W/p_old.csv"
expect_rc 1 pairs --spheres "$W/four.xyzr" --out "$W/p_old.csv" --stats "$W/four.xyzr/stats.json"
expect_file_equals "$W/p_old.csv" 'old\n' "pairs CSV after --stats failed"
[[ -z "$(find "$W" -maxdepth 1 -name '.p_old.csv.tmp-*')" ]] || fail "a temporary pairs file was left behind"
pass

# ----------------------------------------------------------------------------------------------
step "a UTF-8 byte-order mark (as spreadsheets write) is accepted in CSV and XYZR"
printf '\xef\xbb\xbfx,y,z,r\n0,0,0,0.5\n1,0,0,0.5\n100,0,0,1\n101.5,0,0,1\n' >"$W/bom.csv"
expect_rc 0 pairs --spheres "$W/bom.csv" --out "$W/p_bom.csv"
expect_file_equals "$W/p_bom.csv" "$EXPECTED_PAIRS" "pairs of a CSV with BOM"
printf '\xef\xbb\xbf0 0 0 0.5\n1 0 0 0.5\n' >"$W/bom.xyzr"
expect_rc 0 pairs --spheres "$W/bom.xyzr" --out "$W/p_bom2.csv"
expect_file_equals "$W/p_bom2.csv" 'i,j\n0,1\n' "pairs of an XYZR with BOM"
pass

step "binary bytes in a field are escaped in the message (a NUL does not cut it)"
printf '0 0 0 1\n1 \x01\x00\x1b[31m 0 1\n' >"$W/binary.xyzr"
expect_rc 1 pairs --spheres "$W/binary.xyzr" --out "$W/p_bin.csv"
expect_in "$W/err" 'binary.xyzr:2:' "binary field"
expect_in "$W/err" '\x01\x00\x1B[31m' "binary field"
expect_no_control_bytes "$W/err" "binary field"
pass

step "a 1 MB field is cut in the message"
{ printf '0 0 0 '; head -c 1000000 /dev/zero | tr '\0' 'z'; printf '\n'; } >"$W/huge_field.xyzr"
expect_rc 1 pairs --spheres "$W/huge_field.xyzr" --out "$W/p_huge.csv"
[[ "$(wc -c <"$W/err")" -lt 600 ]] || fail "the message echoes the whole field ($(wc -c <"$W/err") bytes)"
expect_in "$W/err" "…" "long field"
pass

# ----------------------------------------------------------------------------------------------
# Hostile box files: each bad file exits 1 with a message naming file:line and what was expected,
# and writes nothing; as --boxes and as --static.
printf 'minx,miny,minz,maxx,maxy,maxz\n0,0,0,1,1,1\n1,0,0,2,1,1\n' >"$W/ok_boxes.csv"
box_case() {  # box_case NAME ROW EXPECTED: a file whose line 3 is ROW must fail with EXPECTED at NAME.csv:3
  printf 'minx,miny,minz,maxx,maxy,maxz\n0,0,0,1,1,1\n%s\n' "$2" >"$W/$1.csv"
  expect_rc 1 pairs --boxes "$W/$1.csv" --out "$W/p_$1.csv"
  expect_in "$W/err" "$W/$1.csv:3: $3" "box file $1"
  expect_no_control_bytes "$W/err" "box file $1"
  [[ ! -e "$W/p_$1.csv" ]] || fail "a failed pairs run wrote its output ($1)"
  expect_rc 1 pairs --boxes "$W/ok_boxes.csv" --static "$W/$1.csv" --out "$W/p_$1.csv"
  expect_in "$W/err" "$W/$1.csv:3: $3" "static box file $1"
}
step "box values: NaN, infinity, |v| > 1e18, beyond float, not a number, min > max"
box_case nan "0,nan,0,1,1,1" "miny = nan is not finite (NaN and infinity are not allowed)"
box_case inf "0,0,0,inf,1,1" "maxx = inf is not finite"
box_case minf "-inf,0,0,1,1,1" "minx = -inf is not finite"
box_case big "0,0,0,1,1,1.5e18" "maxz = 1.5e18 exceeds the supported magnitude 1e18"
box_case negbig "0,0,-2e18,1,1,1" "minz = -2e18 exceeds the supported magnitude 1e18"
box_case float "0,0,0,1,1e39,1" "maxy = '1e39' is out of float range"
box_case word "0,0,0,one,1,1" "maxx: expected a number, found 'one'"
box_case empty "0,0,0,1,,1" "maxy: expected a number, found ''"
box_case minmax "0,0,2,1,1,1" "minz = 2 exceeds maxz = 1 (a box needs min <= max on every axis)"
pass

step "box rows and headers: missing and extra columns, wrong headers, filters, always_active"
box_case short "0,0,0,1,1" "expected 6 numbers \`minx,miny,minz,maxx,maxy,maxz\`, found 5 fields"
box_case long "0,0,0,1,1,1,1" "expected 6 numbers"
box_case blanks "0 0 0 1 1 1" "expected 6 numbers"
printf 'minx,miny,minz,maxx,maxy,maxz,group,mask\n0,0,0,1,1,1,1,1\n0,0,0,1,1,1,1\n' >"$W/nomask.csv"
expect_rc 1 pairs --boxes "$W/nomask.csv" --out "$W/p_nomask.csv"
expect_in "$W/err" "$W/nomask.csv:3: expected 8 fields \`minx,miny,minz,maxx,maxy,maxz,group,mask\`, found 7" "missing mask"
printf 'minx,miny,minz,maxx,maxy,maxz,group,mask\n0,0,0,1,1,1,1,0x1FFFFFFFF\n' >"$W/widemask.csv"
expect_rc 1 pairs --boxes "$W/widemask.csv" --out "$W/p_widemask.csv"
expect_in "$W/err" "$W/widemask.csv:2: mask = 0x1FFFFFFFF does not fit in 32 bits" "mask beyond 32 bits"
printf 'minx,miny,minz,maxx,maxy,maxz,always_active\n0,0,0,1,1,1,yes\n' >"$W/always.csv"
expect_rc 1 pairs --boxes "$W/always.csv" --out "$W/p_always.csv"
expect_in "$W/err" "$W/always.csv:2: always_active: expected 0 or 1, found 'yes'" "bad always_active"
for header in "minx,miny,minz,maxx,maxy" "min_x,min_y,min_z,max_x,max_y,max_z" "minx,miny,minz,maxx,maxy,maxz,mask,group" \
  "0,0,0,1,1,1"; do
  printf '%s\n0,0,0,1,1,1\n' "$header" >"$W/header.csv"
  expect_rc 1 pairs --boxes "$W/header.csv" --out "$W/p_header.csv"
  expect_in "$W/err" "$W/header.csv:1: expected the header \`minx,miny,minz,maxx,maxy,maxz\` or" "header '$header'"
done
printf '\n\nx,y,z,r\n0,0,0,1\n' >"$W/spheres_as_boxes.csv"
expect_rc 1 pairs --boxes "$W/spheres_as_boxes.csv" --out "$W/p_sab.csv"
expect_in "$W/err" "$W/spheres_as_boxes.csv:3: expected the header" "a sphere file as --boxes"
expect_in "$W/err" "a sphere file, where boxes were expected" "a sphere file as --boxes"
[[ -z "$(find "$W" -maxdepth 1 -name 'p_*.csv' -newer "$W/ok_boxes.csv")" ]] || fail "a failed box run wrote its output"
pass

step "a --static file of the other kind: exit 1 naming file:line and the kind expected"
printf 'x,y,z,r\n0,0,0,1\n' >"$W/static_spheres.csv"
expect_rc 1 pairs --boxes "$W/ok_boxes.csv" --static "$W/static_spheres.csv" --out "$W/p_kind.csv"
expect_in "$W/err" "$W/static_spheres.csv:1: a sphere file (header \`x,y,z,r\`), but the moving objects (--boxes) are boxes" \
  "sphere --static with boxes"
printf '# rocks\n0 0 0 1\n' >"$W/static_spheres.xyzr"
expect_rc 1 query --boxes "$W/ok_boxes.csv" --static "$W/static_spheres.xyzr" --overlap 0,0,0,1
expect_in "$W/err" "$W/static_spheres.xyzr:2: a sphere file (XYZR" "XYZR --static with boxes"
expect_rc 1 pairs --spheres "$W/four.xyzr" --static "$W/ok_boxes.csv" --out "$W/p_kind.csv"
expect_in "$W/err" "$W/ok_boxes.csv:1: a box file" "box --static with spheres"
expect_in "$W/err" "--static must hold spheres too" "box --static with spheres"
# An empty static file has no kind: it is an empty static set.
: >"$W/static_empty.csv"
expect_rc 0 pairs --boxes "$W/ok_boxes.csv" --static "$W/static_empty.csv" --out "$W/p_empty_static.csv"
expect_file_equals "$W/p_empty_static.csv" 'i,j\n0,1\n' "an empty static file"
[[ ! -e "$W/p_kind.csv" ]] || fail "a refused static file let pairs write its output"
pass

step "box files: binary bytes escaped, a 1 MB field cut, a byte-order mark accepted"
printf 'minx,miny,minz,maxx,maxy,maxz\n0,\x01\x00\x1b[31m,0,1,1,1\n' >"$W/binary_boxes.csv"
expect_rc 1 pairs --boxes "$W/binary_boxes.csv" --out "$W/p_binb.csv"
expect_in "$W/err" "binary_boxes.csv:2: miny" "binary box field"
expect_in "$W/err" '\x01\x00\x1B[31m' "binary box field"
expect_no_control_bytes "$W/err" "binary box field"
{ printf 'minx,miny,minz,maxx,maxy,maxz\n0,0,0,1,1,'; head -c 1000000 /dev/zero | tr '\0' '9'; printf '\n'; } \
  >"$W/huge_boxes.csv"
expect_rc 1 pairs --boxes "$W/huge_boxes.csv" --out "$W/p_hugeb.csv"
[[ "$(wc -c <"$W/err")" -lt 600 ]] || fail "the message echoes the whole field ($(wc -c <"$W/err") bytes)"
expect_in "$W/err" "huge_boxes.csv:2: maxz" "long box field"
printf '\xef\xbb\xbfminx,miny,minz,maxx,maxy,maxz\n0,0,0,1,1,1\n1,1,1,2,2,2\n' >"$W/bom_boxes.csv"
expect_rc 0 pairs --boxes "$W/bom_boxes.csv" --out "$W/p_bomb.csv"
expect_file_equals "$W/p_bomb.csv" 'i,j\n0,1\n' "pairs of a box CSV with BOM"
pass

step "an option value with control characters is escaped"
expect_rc 2 pairs --spheres "$W/four.xyzr" --bits "$(printf '1\x1b[2J6')"
expect_in "$W/err" '\x1B' "escaped option value"
expect_no_control_bytes "$W/err" "option value"
pass

step "--dt inf names --dt (not sphere 0)"
expect_rc 2 run --dt inf --frames 1 --objects 10 --out "$W/r4"
expect_in "$W/err" "--dt" "--dt inf"
pass

step "an open error says why (errno)"
expect_rc 1 pairs --spheres "$W/missing.xyzr" --out "$W/p_missing.csv"
expect_in "$W/err" "No such file or directory" "missing file"
pass

step "unknown options and bad values exit 2 (not CLI11's 104-114)"
expect_rc 2 pairs --spheres "$W/four.xyzr" --frobnicate
expect_rc 2 run --objects many
expect_rc 2 pairs --spheres "$W/four.xyzr" --validate-hash xyz
pass

# ----------------------------------------------------------------------------------------------
step "bench paper rejects --frames 0, --sizes 0, --warmup -1, --backend foo at once"
expect_rc 2 bench paper --frames 0 --out "$W/b1"
expect_in "$W/err" "--frames" "bench --frames 0"
expect_rc 2 bench paper --sizes 0 --out "$W/b2"
expect_in "$W/err" "--sizes" "bench --sizes 0"
expect_rc 2 bench paper --warmup -1 --out "$W/b3"
expect_in "$W/err" "--warmup" "bench --warmup -1"
expect_rc 2 bench paper --backend foo --out "$W/b4"
[[ ! -e "$W/b1" && ! -e "$W/b2" && ! -e "$W/b3" && ! -e "$W/b4" ]] || fail "a refused bench created its folder"
pass

step "--geometry foo and --counter foo are usage errors on every backend"
expect_rc 2 pairs --spheres "$W/four.xyzr" --geometry foo --out "$W/p_geo.csv"
expect_in "$W/err" "--geometry" "--geometry foo on cpu"
expect_rc 2 pairs --spheres "$W/four.xyzr" --counter foo --backend reference --out "$W/p_ctr.csv"
expect_in "$W/err" "--counter" "--counter foo on reference"
pass

PEERS="$(dirname "$VISCD")/viscd_peers"
if [[ -x "$PEERS" ]]; then
  step "viscd bench peers -- ARGS hands ARGS to the driver (the command docs/usage.md shows)"
  expect_rc 0 bench peers -- --help
  expect_in "$W/out" "--objects" "bench peers -- --help"
  expect_rc 0 bench peers -- --objects 300 --frames 1 --repeats 1 --csv "$W/peers.csv"
  [[ -s "$W/peers.csv" ]] || fail "bench peers -- --csv wrote nothing"
  pass
fi

step "gl: a single frame's --stats holds the real stage times (not zeros)"
set +e
"$VISCD" pairs --spheres "$W/row.xyzr" --camera "$W/cam.json" --backend gl --out "$W/p_gl.csv" \
  --stats "$W/s_gl.json" >"$W/out" 2>"$W/err"
rc=$?
set -e
if [[ "$rc" -ne 0 ]] && grep -q "OpenGL\|EGL\|not built" "$W/err"; then
  echo "    skipped: no OpenGL 4.5 context here ($(head -n1 "$W/err"))"
else
  [[ "$rc" -eq 0 ]] || { show pairs gl; fail "gl pairs exited $rc"; }
  python3 - "$W/s_gl.json" <<'PY' || fail "gl --stats reports zero stage times"
import json, sys
ms = json.load(open(sys.argv[1]))["stage_ms"]
assert ms["visibility"] > 0 and ms["count"] > 0 and ms["sort"] > 0 and ms["query"] > 0, ms
PY
  pass
fi

echo "hostile_test.sh: all $checks checks passed"
