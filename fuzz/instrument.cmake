# Included from the top-level CMakeLists.txt when VISCD_BUILD_FUZZ is on, before any target is
# defined: every target of the project (the library included) is compiled with libFuzzer's
# coverage instrumentation plus ASan and UBSan, so the fuzzers in this folder see the library's
# branches and any memory error or undefined behaviour in it stops the run. UBSan does not
# recover: a report is a crash that libFuzzer saves as a reproducer.
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "VISCD_BUILD_FUZZ needs Clang with libFuzzer (Debian: clang, libclang-rt-14-dev); "
                      "CMAKE_CXX_COMPILER is ${CMAKE_CXX_COMPILER_ID} ${CMAKE_CXX_COMPILER}. "
                      "Use `cmake --preset fuzz` or pass -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++.")
endif()
add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
# Executables other than the fuzzers (tests, tools) link the sanitizer runtimes; the fuzzers add
# libFuzzer itself (fuzz/CMakeLists.txt).
add_link_options(-fsanitize=address,undefined)
