#!/usr/bin/env bash
# `mpirun -np K viscd pairs ...` writes what one process writes, byte for byte, for K = 1..4, and
# fails every rank alike. Usage: VISCD=... MPIRUN=... mpi_cli_test.sh WORKDIR
set -euo pipefail
source "$(dirname "$0")/cli_lib.sh"
: "${MPIRUN:?set MPIRUN to mpirun}"

# Runs the tool on K ranks, keeping stdout, stderr and the exit status as run() does.
mrun() {  # mrun K ARGS...
  local k="$1"
  shift
  set +e
  "$MPIRUN" -np "$k" "$VISCD" "$@" >"$W/out" 2>"$W/err"
  rc=$?
  set -e
}

# Scenes, from awk's seeded generator: x y z r (with group,mask,always_active), boxes, static.
awk 'BEGIN { srand(7); print "x,y,z,r,group,mask,always_active";
  for (i = 0; i < 6000; i++) printf "%.4f,%.4f,%.4f,%.4f,%d,%d,%d\n", rand()*100, rand()*100, rand()*20,
    0.2 + rand()*1.3, 2^int(rand()*3), 4294967295 - 2^int(rand()*3), (rand() < 0.1) }' >"$W/uniform.csv"
awk 'BEGIN { srand(8); print "x,y,z,r";
  for (i = 0; i < 300; i++) printf "%.4f,%.4f,%.4f,%.4f\n", rand()*100, rand()*100, rand()*20, 0.5 + rand()*3 }' \
  >"$W/static.csv"
awk 'BEGIN { srand(9); print "minx,miny,minz,maxx,maxy,maxz";
  for (i = 0; i < 3000; i++) { x = rand()*40; y = rand()*40; z = rand()*40; e = 0.2 + rand()*2;
    printf "%.4f,%.4f,%.4f,%.4f,%.4f,%.4f\n", x, y, z, x + e, y + e, z + e } }' >"$W/boxes.csv"
awk 'BEGIN { srand(10); print "minx,miny,minz,maxx,maxy,maxz";
  for (i = 0; i < 200; i++) { x = rand()*40; y = rand()*40; printf "%.4f,%.4f,0,%.4f,%.4f,3\n", x, y, x + 4, y + 1 } }' \
  >"$W/static_boxes.csv"
# Flat, on one plane, and packed around x = 50 where two slabs meet.
awk 'BEGIN { srand(11); print "x,y,z,r"; for (i = 0; i < 4000; i++) printf "%.4f,%.4f,0,%.4f\n", rand()*100, rand()*100, 0.3 + rand() }' \
  >"$W/flat.csv"
awk 'BEGIN { srand(12); print "x,y,z,r"; for (i = 0; i < 3000; i++) printf "%.4f,%.4f,%.4f,%.4f\n", 50 + (rand()-0.5)*4, rand()*30, rand()*30, 0.3 + rand() }' \
  >"$W/seam.csv"
# One sphere over everything, and fewer objects than ranks.
{ echo "x,y,z,r"; echo "50,50,50,500"; awk 'BEGIN { srand(13); for (i = 0; i < 500; i++) printf "%.3f,%.3f,%.3f,0.5\n", rand()*100, rand()*100, rand()*100 }'; } >"$W/huge.csv"
printf 'x,y,z,r\n0,0,0,1\n1.5,0,0,1\n' >"$W/two.csv"
printf 'x,y,z,r\n' >"$W/empty.csv"

same_as_one_process() {  # same_as_one_process WHAT ARGS... (ARGS without --out)
  local what="$1"
  shift
  expect_rc 0 pairs "$@" --out "$W/one.csv"
  for k in 1 2 3 4; do
    mrun "$k" pairs "$@" --out "$W/k$k.csv" --stats "$W/k$k.json"
    if [[ "$rc" -ne 0 ]]; then
      show "mpirun -np $k viscd pairs $*"
      fail "$what: mpirun -np $k exited $rc"
    fi
    cmp -s "$W/one.csv" "$W/k$k.csv" || fail "$what: $k ranks wrote another pairs file than one process"
    expect_in "$W/k$k.json" "\"ranks\": $k" "$what: stats of $k ranks"
  done
}

step "spheres with filters and always_active, and a static set: 1-4 ranks equal one process"
same_as_one_process "uniform" --spheres "$W/uniform.csv" --static "$W/static.csv"
[[ $(wc -l <"$W/one.csv") -gt 100 ]] || fail "uniform: too few pairs to tell anything"
pass

step "boxes with static boxes"
same_as_one_process "boxes" --boxes "$W/boxes.csv" --static "$W/static_boxes.csv"
pass

step "flat, packed on a slab seam, one huge sphere, fewer objects than ranks, none"
same_as_one_process "flat" --spheres "$W/flat.csv"
same_as_one_process "seam" --spheres "$W/seam.csv"
same_as_one_process "huge" --spheres "$W/huge.csv"
same_as_one_process "two" --spheres "$W/two.csv"
expect_file_equals "$W/k4.csv" 'i,j\n0,1\n' "two objects on four ranks"
same_as_one_process "empty" --spheres "$W/empty.csv"
pass

step "a NaN fails every rank with the file's line and exit 1, and writes nothing"
printf 'x,y,z,r\n1,2,3,1\nnan,1,1,1\n' >"$W/bad.csv"
rm -f "$W/bad_out.csv"
mrun 3 pairs --spheres "$W/bad.csv" --out "$W/bad_out.csv"
[[ "$rc" -eq 1 ]] || { show pairs --spheres bad.csv; fail "a NaN under mpirun exited $rc, expected 1"; }
expect_in "$W/err" "bad.csv:3: x = nan" "the NaN's message"
[[ $(grep -c "viscd: error" "$W/err") -eq 1 ]] || fail "the error was printed more than once (only rank 0 speaks)"
[[ ! -e "$W/bad_out.csv" ]] || fail "a failed run wrote its output"
pass

step "--validate-hash under mpirun: exit 3 on a mismatch"
mrun 2 pairs --spheres "$W/two.csv" --out "$W/h.csv" --validate-hash 0000000000000000
[[ "$rc" -eq 3 ]] || { show pairs --validate-hash; fail "a hash mismatch under mpirun exited $rc, expected 3"; }
pass

step "culling and other commands are refused under mpirun with more than one rank (exit 2)"
printf '{"eye":[0,0,50],"target":[0,0,0]}\n' >"$W/cam.json"
mrun 2 pairs --spheres "$W/two.csv" --camera "$W/cam.json" --out "$W/c.csv"
[[ "$rc" -eq 2 ]] || { show pairs --camera; fail "--camera under mpirun exited $rc, expected 2"; }
expect_in "$W/err" "culling is off" "--camera refused"
mrun 2 run --frames 1
[[ "$rc" -eq 2 ]] || { show run; fail "viscd run under mpirun -np 2 exited $rc, expected 2"; }
expect_in "$W/err" "only \`viscd pairs\`" "run refused"
pass

echo "all $checks checks passed"
