#!/usr/bin/env bash
# Installs the built viscd into a scratch prefix and uses it from separate projects:
#  - examples/game_loop.cpp with find_package(viscd) and viscd::viscd alone, which must link
#    nothing but Threads (and libepoxy, link-only, for the gl backend);
#  - examples/engine_loop.cpp (when viscd was built with the gl backend): the engine's own
#    G-buffer and id texture, events, filters, a ray query, in the engine's context;
#  - tests/install/tools/ with find_package(viscd COMPONENTS tools) and viscd::tools;
#  - tests/install/mpi/ with find_package(viscd COMPONENTS mpi) and viscd::mpi on two ranks, when
#    viscd was built with MPI;
#  - tests/install/missing_component/: a component viscd does not have is not found.
# Neither consumer may need nlohmann_json: it is disabled for them.
# Usage: install_test.sh BUILD_DIR WORK_DIR
set -euo pipefail
build="$1" work="$2"
here="$(cd "$(dirname "$0")" && pwd)"
rm -rf "$work" && mkdir -p "$work"
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" >/dev/null
# The licence travels with the library (and with the Python package, when it is built).
[[ -f "$prefix/share/doc/viscd/LICENSE" ]] || { echo "install test: LICENSE is not installed" >&2; exit 1; }
consumer_flags=(-DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release -DCMAKE_DISABLE_FIND_PACKAGE_nlohmann_json=ON
                --no-warn-unused-cli)

# viscd::viscd's link interface, from the installed targets file: each entry must be Threads
# (or pthread) or, only as $<LINK_ONLY:...> (a static library's own link needs), epoxy.
# $<LINK_ONLY:> is what a dependency of the build tree only ($<BUILD_INTERFACE:...>) leaves.
# Built with the cuda backend, the CUDA runtime is linked statically, link-only as well: a
# consumer's link needs the toolkit's libcudart_static.a (viscdConfig.cmake finds CUDAToolkit).
targets="$(ls "$prefix"/lib*/cmake/viscd/viscdTargets.cmake)"
links="$(sed -n '/^set_target_properties(viscd::viscd PROPERTIES/,/^)/p' "$targets" |
         sed -n 's/^ *INTERFACE_LINK_LIBRARIES "\(.*\)"$/\1/p')"
echo "install test: viscd::viscd INTERFACE_LINK_LIBRARIES = ${links:-(none)}"
IFS=';' read -ra entries <<<"$links"
for entry in "${entries[@]}"; do
  case "$entry" in
    Threads::Threads | pthread | -pthread | '\$<LINK_ONLY:epoxy>' | '\$<LINK_ONLY:>' | '\$<LINK_ONLY:CUDA::cudart_static>') ;;
    *) echo "FAIL: viscd::viscd links '$entry' (only Threads, and epoxy and the CUDA runtime link-only, allowed)" >&2; exit 1 ;;
  esac
done
[[ " ${entries[*]} " == *" Threads::Threads "* ]] || { echo "FAIL: viscd::viscd does not link Threads" >&2; exit 1; }
if grep -rqi "nlohmann\|viscd_options" "$prefix"/lib*/cmake/viscd/; then
  echo "FAIL: the installed package names nlohmann_json or viscd_options:" >&2
  grep -rni "nlohmann\|viscd_options" "$prefix"/lib*/cmake/viscd/ >&2
  exit 1
fi

with_gl=OFF
grep -q "^VISCD_ENABLE_GL:BOOL=ON" "$build/CMakeCache.txt" && with_gl=ON
cmake -S "$here" -B "$work/consumer" "${consumer_flags[@]}" -DVISCD_CONSUMER_GL=$with_gl >/dev/null
cmake --build "$work/consumer" >/dev/null
"$work/consumer/game_loop" | tee "$work/out.txt"
grep -q "tick  *80:" "$work/out.txt"
echo "install test: find_package(viscd) + game_loop OK"
if [[ $with_gl == ON ]]; then
  "$work/consumer/engine_loop" | tee "$work/engine_out.txt"
  grep -q "tick  *60:" "$work/engine_out.txt"
  echo "install test: engine_loop (the engine's id texture, events, filters, a ray query) OK"
fi

cmake -S "$here/tools" -B "$work/tools_consumer" "${consumer_flags[@]}" >/dev/null
cmake --build "$work/tools_consumer" >/dev/null
"$work/tools_consumer/tools_consumer" "$work/tools_spheres.csv" | tee "$work/tools_out.txt"
grep -q "^tools: 500 spheres written and read back" "$work/tools_out.txt"
head -n 1 "$work/tools_spheres.csv" | grep -q "^x,y,z,r$" || { echo "FAIL: tools_consumer wrote no CSV header" >&2; exit 1; }
echo "install test: find_package(viscd COMPONENTS tools) + viscd::tools OK"

if cmake -S "$here/missing_component" -B "$work/missing_required" -DVISCD_REQUIRED=ON "${consumer_flags[@]}" \
     >"$work/missing_required.txt" 2>&1; then
  echo "FAIL: find_package(viscd REQUIRED COMPONENTS nonexistent) configured" >&2
  cat "$work/missing_required.txt" >&2
  exit 1
fi
grep -q "viscd has no component 'nonexistent'" "$work/missing_required.txt" || {
  echo "FAIL: a missing required component gave no message naming it:" >&2
  cat "$work/missing_required.txt" >&2
  exit 1
}
cmake -S "$here/missing_component" -B "$work/missing_quiet" "${consumer_flags[@]}" >"$work/missing_quiet.txt" 2>&1 || {
  cat "$work/missing_quiet.txt" >&2
  exit 1
}
echo "install test: a component viscd does not have is not found"

# find_package(viscd COMPONENTS mpi) and viscd::mpi on two ranks, when viscd was built with MPI.
if ls "$prefix"/lib*/cmake/viscd/viscdMpiTargets.cmake >/dev/null 2>&1 && command -v mpirun >/dev/null; then
  cmake -S "$here/mpi" -B "$work/mpi_consumer" "${consumer_flags[@]}" >/dev/null
  cmake --build "$work/mpi_consumer" >/dev/null
  # Open MPI keeps allocations until exit: no leak check for this one under ASan.
  ASAN_OPTIONS=detect_leaks=0 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 \
    mpirun -np 2 "$work/mpi_consumer/mpi_consumer" | tee "$work/mpi_out.txt"
  grep -q "2 ranks, 3 pairs, a chain" "$work/mpi_out.txt"
  echo "install test: find_package(viscd COMPONENTS mpi) + viscd::mpi OK"
fi

# The installed tool finds what `viscd bench` needs in the prefix, not in the build tree.
if [[ -x "$prefix/bin/viscd" ]]; then
  [[ -f "$prefix/share/viscd/plot_paper.py" ]] || { echo "FAIL: share/viscd/plot_paper.py not installed" >&2; exit 1; }
  if [[ -f "$build/viscd_peers" ]]; then
    [[ -x "$prefix/libexec/viscd/viscd_peers" ]] || { echo "FAIL: libexec/viscd/viscd_peers not installed" >&2; exit 1; }
    # Run from a copy of the prefix elsewhere, so that nothing next to the build tree is found.
    cp -r "$prefix" "$work/moved"
    "$work/moved/bin/viscd" bench peers -- --help >"$work/peers.txt"
    grep -q -- "--objects" "$work/peers.txt" || { echo "FAIL: installed viscd bench peers" >&2; exit 1; }
  fi
  echo "install test: bench scripts and the peers driver installed and found"
fi
