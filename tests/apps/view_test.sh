#!/usr/bin/env bash
# Window tests of `viscd view` under Xvfb: it opens a window, runs frames, writes a screenshot
# that shows all three colour classes (and static objects, grey, as spheres or boxes), fails
# clearly without a display, and falls back from a gl backend that cannot start to cpu.
# Usage: VISCD=/path/to/viscd bash tests/apps/view_test.sh WORKDIR
# Exits 77 (ctest: skipped) when xvfb-run or python3 is missing.
set -euo pipefail

for tool in xvfb-run python3; do
  if ! command -v "$tool" >/dev/null; then
    echo "SKIP: $tool is not installed (apt-get install xvfb xauth python3)"
    exit 77
  fi
done

# The usage check, the work folder ($W), fail and step; run is this script's own, below.
source "$(dirname "$0")/cli_lib.sh"
WORK="$W"
XVFB=(xvfb-run -a -s "-screen 0 1280x800x24")

run() {  # run [PREFIX...] -- ARGS...: stdout in $WORK/out, stderr in $WORK/err, status in $rc
  local prefix=()
  while [[ "$1" != "--" ]]; do
    prefix+=("$1")
    shift
  done
  shift
  set +e
  "${prefix[@]}" "$VISCD" "$@" >"$WORK/out" 2>"$WORK/err"
  rc=$?
  set -e
}
show() {
  echo "    exit status: $rc" >&2
  echo "    stdout:" >&2
  sed 's/^/      /' "$WORK/out" >&2 || true
  echo "    stderr:" >&2
  sed 's/^/      /' "$WORK/err" >&2 || true
}

# Checks a PNG: size (WxH or "any") and, with "colours", pixels of all three classes; with
# "colours+static" grey static objects' too.
# A small decoder for 8-bit RGB/RGBA non-interlaced PNGs, standard library only.
check_png() {  # check_png FILE SIZE [colours|colours+static]
  python3 - "$@" <<'PY'
import struct, sys, zlib

path, want_size = sys.argv[1], sys.argv[2]
want_colours = len(sys.argv) > 3 and sys.argv[3] in ("colours", "colours+static")
want_static = len(sys.argv) > 3 and sys.argv[3] == "colours+static"
data = open(path, "rb").read()
if data[:8] != b"\x89PNG\r\n\x1a\n":
    sys.exit(f"{path}: not a PNG (bad signature)")
pos, idat, ihdr = 8, [], None
while pos < len(data):
    length, kind = struct.unpack(">I4s", data[pos:pos + 8])
    body = data[pos + 8:pos + 8 + length]
    if zlib.crc32(kind + body) != struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])[0]:
        sys.exit(f"{path}: bad CRC in chunk {kind!r}")
    if kind == b"IHDR":
        ihdr = struct.unpack(">IIBBBBB", body)
    elif kind == b"IDAT":
        idat.append(body)
    elif kind == b"IEND":
        break
    pos += 12 + length
if ihdr is None:
    sys.exit(f"{path}: no IHDR")
w, h, depth, ctype, _, _, interlace = ihdr
if depth != 8 or ctype not in (2, 6) or interlace != 0:
    sys.exit(f"{path}: decoder handles 8-bit RGB/RGBA non-interlaced only, got depth {depth} type {ctype} interlace {interlace}")
if want_size != "any" and f"{w}x{h}" != want_size:
    sys.exit(f"{path}: size {w}x{h}, expected {want_size}")
bpp = 4 if ctype == 6 else 3
stride = w * bpp
raw = zlib.decompress(b"".join(idat))
if len(raw) != h * (stride + 1):
    sys.exit(f"{path}: {len(raw)} bytes of image data, expected {h * (stride + 1)}")
prev = bytearray(stride)
counts = {"red": 0, "blue": 0, "yellow": 0}
if want_static:
    counts["grey"] = 0
for y in range(h):
    f = raw[y * (stride + 1)]
    line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
    if f == 1:
        for i in range(bpp, stride):
            line[i] = (line[i] + line[i - bpp]) & 255
    elif f == 2:
        for i in range(stride):
            line[i] = (line[i] + prev[i]) & 255
    elif f == 3:
        for i in range(stride):
            left = line[i - bpp] if i >= bpp else 0
            line[i] = (line[i] + ((left + prev[i]) >> 1)) & 255
    elif f == 4:
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            p = a + b - c
            pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            line[i] = (line[i] + pred) & 255
    elif f != 0:
        sys.exit(f"{path}: row {y} has unknown filter {f}")
    if want_colours:
        for i in range(0, stride, bpp):
            r, g, b = line[i], line[i + 1], line[i + 2]
            if want_static and r > 40 and abs(r - g) <= 12 and 0 <= b - r <= 30:
                counts["grey"] += 1  # static (140, 140, 150) shaded: blue only a little above red and green
            elif r > 2 * g and r > 2 * b:
                counts["red"] += 1
            elif b > r and b > g and b > 80:
                counts["blue"] += 1
            elif r > b + 40 and g > b + 40:
                counts["yellow"] += 1
    prev = line
print(f"    {path}: {w}x{h}" + (f", pixels {counts}" if want_colours else ""))
missing = [k for k, v in counts.items() if v == 0]
if want_colours and missing:
    sys.exit(f"{path}: no {', '.join(missing)} pixels (colliding red, free blue, culled yellow"
             + (", static grey" if want_static else "") + " expected)")
PY
}

step "no display: a clear error naming DISPLAY and xvfb-run, exit 1"
run env -u DISPLAY -u WAYLAND_DISPLAY -- view --frames 1
if [[ "$rc" -ne 1 ]]; then
  show
  fail "viscd view without a display exited $rc, expected 1"
fi
grep -q "DISPLAY" "$WORK/err" || { show; fail "the error does not name DISPLAY"; }
grep -q "xvfb-run" "$WORK/err" || { show; fail "the error does not suggest xvfb-run"; }
echo "    ok"

step "a bad option is refused before any window opens"
run env -u DISPLAY -- view --backend reference
[[ "$rc" -ne 0 ]] && grep -q -- "--backend" "$WORK/err" || { show; fail "view --backend reference was not refused"; }
echo "    ok"

step "bad option values are usage errors (exit 2), a bad camera file bad input (exit 1)"
for bad in "--objects 0" "--frames -1" "--backend reference" "--camera sideways"; do
  # shellcheck disable=SC2086 # the option and its value are two words
  run env -u DISPLAY -- view $bad
  [[ "$rc" -eq 2 ]] || { show; fail "view $bad exited $rc, expected 2"; }
done
run env -u DISPLAY -- view --camera "$(printf 'odd\tname')"
[[ "$rc" -eq 2 ]] && grep -qF 'odd\tname' "$WORK/err" || { show; fail "a control character in --camera was not escaped"; }
echo '{"eye": [0, 0, 10], "bogus": 1}' >"$WORK/badcam.json"
run env -u DISPLAY -- view --camera "$WORK/badcam.json"
[[ "$rc" -eq 1 ]] && grep -q "badcam.json" "$WORK/err" || { show; fail "view with a bad camera file exited $rc, expected 1"; }
echo "    ok"

step "20 frames in a 640x360 window, screenshot with colliding, free and culled objects"
run "${XVFB[@]}" -- view --objects 3000 --frames 20 --size 640x360 --lambda 100 --screenshot "$WORK/view.png" \
  --window-screenshot "$WORK/window.png"
if [[ "$rc" -ne 0 ]]; then
  show
  fail "viscd view exited $rc"
fi
[[ -s "$WORK/view.png" ]] || { show; fail "no screenshot at $WORK/view.png"; }
grep -q "wrote $WORK/view.png" "$WORK/out" || { show; fail "the screenshot path is not printed"; }
grep -q "20 frames" "$WORK/out" || { show; fail "no summary of the 20 frames"; }
check_png "$WORK/view.png" 640x360 colours || fail "screenshot check"
check_png "$WORK/window.png" 640x360 || fail "window screenshot check"
echo "    ok"

step "boxes on a static field (--shape box --static): the screenshot shows every class and grey static objects"
run "${XVFB[@]}" -- view --objects 3000 --frames 10 --size 640x360 --lambda 100 --shape box --static 300 \
  --screenshot "$WORK/boxes.png"
[[ "$rc" -eq 0 ]] || { show; fail "viscd view --shape box --static 300 exited $rc"; }
grep -q "^viscd view: cpu backend, 3000 boxes (ring scene) + 300 static" "$WORK/out" || { show; fail "no start line"; }
grep -q "10 frames, last: .* objects active, 300 static," "$WORK/out" || { show; fail "no summary with the static count"; }
check_png "$WORK/boxes.png" 640x360 colours+static || fail "box screenshot check"
# The same in spheres: the spheres' image differs from the boxes'.
run "${XVFB[@]}" -- view --objects 3000 --frames 10 --size 640x360 --lambda 100 --static 300 --screenshot "$WORK/rocks.png"
[[ "$rc" -eq 0 ]] || { show; fail "viscd view --static 300 exited $rc"; }
check_png "$WORK/rocks.png" 640x360 colours+static || fail "sphere screenshot with a static field"
cmp -s "$WORK/boxes.png" "$WORK/rocks.png" && fail "boxes and spheres gave the same image"
run env -u DISPLAY -- view --shape cube
[[ "$rc" -eq 2 ]] && grep -q -- "--shape" "$WORK/err" || { show; fail "view --shape cube exited $rc, expected 2"; }
echo "    ok"

step "--backend gl with boxes and a static set: gl takes them"
run "${XVFB[@]}" -- view --backend gl --objects 1000 --frames 3 --size 320x180 --lambda 60 --shape box --static 50 \
  --screenshot "$WORK/gl_boxes.png"
[[ "$rc" -eq 0 ]] || { show; fail "viscd view --backend gl --shape box exited $rc"; }
if grep -q "does not take" "$WORK/err"; then show; fail "gl refused boxes or a static set"; fi
grep -q "3 frames, last:" "$WORK/out" || { show; fail "no summary of the 3 frames"; }
check_png "$WORK/gl_boxes.png" 320x180 || fail "gl box screenshot check"
echo "    ok"

step "gl backend (impostor) in the window, or a clear fallback to cpu"
run "${XVFB[@]}" -- view --backend gl --objects 2000 --frames 5 --size 480x270 --lambda 60 --map-size 240x135 \
  --screenshot "$WORK/gl.png"
if [[ "$rc" -ne 0 ]]; then
  show
  fail "viscd view --backend gl exited $rc"
fi
if grep -q "gl backend unavailable" "$WORK/err"; then
  echo "    (gl backend not available here, fell back to cpu: $(head -n 1 "$WORK/err"))"
fi
check_png "$WORK/gl.png" 240x135 || fail "gl screenshot check"
echo "    ok"

# __EGL_VENDOR_LIBRARY_FILENAMES naming no file leaves libglvnd with no EGL driver (the gl
# backend's context) while the window's GLX context still opens: gl cannot start.
step "--backend gl that cannot start falls back to cpu, says why on stderr, and runs"
run env __EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/viscd-no-egl-vendor.json "${XVFB[@]}" -- view --backend gl \
  --objects 1000 --frames 3 --size 320x180 --lambda 60 --screenshot "$WORK/fallback.png"
if [[ "$rc" -ne 0 ]]; then
  show
  fail "viscd view --backend gl without an EGL driver exited $rc"
fi
if grep -q "viscd view: gl backend, " "$WORK/out"; then
  echo "    skipped: the EGL vendor override did not take here"
else
  grep -q "^viscd view: gl backend unavailable: .*; staying on cpu$" "$WORK/err" ||
    { show; fail "no 'gl backend unavailable: ...; staying on cpu' message"; }
  grep -q "^viscd view: cpu backend, 1000 objects" "$WORK/out" || { show; fail "the viewer does not say it runs cpu"; }
  grep -q "3 frames, last:" "$WORK/out" || { show; fail "no summary of the 3 frames"; }
  check_png "$WORK/fallback.png" 320x180 || fail "fallback screenshot check"
  echo "    ok"
fi

echo "view_test: all $checks checks passed"
