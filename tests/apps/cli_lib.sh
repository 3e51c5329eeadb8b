# Helpers shared by the command-line test scripts (sourced, not run).
# Expects: $1 = WORKDIR, $VISCD = the viscd binary. Defines run/expect_* helpers; $W is the work folder.

if [[ $# -ne 1 ]]; then
  echo "usage: VISCD=/path/to/viscd $0 WORKDIR" >&2
  exit 2
fi
: "${VISCD:?set VISCD to the viscd binary}"
if [[ ! -x "$VISCD" ]]; then
  echo "FAIL: VISCD=$VISCD is not an executable" >&2
  exit 1
fi

W="$1"
rm -rf "$W"
mkdir -p "$W"

checks=0
fail() {
  echo "FAIL: $*" >&2
  exit 1
}
step() {
  checks=$((checks + 1))
  echo "--- [$checks] $*"
}
pass() { echo "    ok"; }

# Runs the tool, keeping stdout in $W/out, stderr in $W/err and the exit status in $rc.
rc=0
run() {
  set +e
  "$VISCD" "$@" >"$W/out" 2>"$W/err"
  rc=$?
  set -e
}
show() {
  echo "    command: viscd $*" >&2
  echo "    exit status: $rc" >&2
  echo "    stdout:" >&2
  sed 's/^/      /' "$W/out" >&2 || true
  echo "    stderr:" >&2
  sed 's/^/      /' "$W/err" >&2 || true
}
expect_rc() {  # expect_rc CODE ARGS...
  local want="$1"
  shift
  run "$@"
  if [[ "$rc" -ne "$want" ]]; then
    show "$@"
    fail "viscd $* exited $rc, expected $want"
  fi
}
expect_nonzero() {
  run "$@"
  if [[ "$rc" -eq 0 ]]; then
    show "$@"
    fail "viscd $* exited 0, expected a failure"
  fi
}
expect_in() {  # expect_in FILE TEXT WHAT
  if ! grep -qF -- "$2" "$1"; then
    echo "    $(basename "$1"):" >&2
    sed 's/^/      /' "$1" >&2 || true
    fail "$3: '$2' not found in $(basename "$1")"
  fi
}
expect_file_equals() {  # expect_file_equals FILE EXPECTED_TEXT WHAT
  if [[ ! -f "$1" ]]; then fail "$3: $1 was not written"; fi
  if ! cmp -s "$1" <(printf '%b' "$2"); then
    echo "    expected:" >&2
    printf '%b' "$2" | sed 's/^/      /' >&2
    echo "    got:" >&2
    sed 's/^/      /' "$1" >&2
    fail "$3: $1 differs from the expected text"
  fi
}

