# Runs one libFuzzer target for a bounded time (the `fuzz` ctest tests, fuzz/CMakeLists.txt).
#   cmake -DFUZZER=<binary> -DSEEDS=<seed corpus dir> -DWORK=<scratch dir> -DSECONDS=<n> -DMAX_LEN=<bytes>
#         -P run_fuzzer.cmake
# The seed corpus is copied into WORK/corpus first, so new inputs land in the build tree and the
# repository's corpus stays as committed. A crash leaves its input in WORK/artifacts.
foreach(var FUZZER SEEDS WORK SECONDS MAX_LEN)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run_fuzzer.cmake: -D${var}=... is required")
  endif()
endforeach()
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK}/corpus ${WORK}/artifacts)
file(GLOB seeds ${SEEDS}/*)
if(seeds)
  file(COPY ${seeds} DESTINATION ${WORK}/corpus)
endif()
execute_process(COMMAND ${FUZZER} -max_total_time=${SECONDS} -rss_limit_mb=2048 -timeout=10 -max_len=${MAX_LEN}
                        -print_final_stats=1 -artifact_prefix=${WORK}/artifacts/ ${WORK}/corpus
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  file(GLOB found ${WORK}/artifacts/*)
  message(FATAL_ERROR "${FUZZER} failed (${rc}). Reproducer(s): ${found}\n"
                      "Rerun one with: ${FUZZER} <file>")
endif()
