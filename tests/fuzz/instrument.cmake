# Included by the top-level CMakeLists.txt when MKTREE_BUILD_FUZZERS is on, before any library is defined:
# every library is compiled with libFuzzer's coverage instrumentation and ASan + UBSan, so that the fuzz
# targets (tests/fuzz) are guided by coverage inside them and a memory error or UB in them is a crash.
# UBSan stays recoverable, so that a campaign can look past a known finding with a suppressions file;
# scripts/fuzz.sh and the replay tests set UBSAN_OPTIONS=halt_on_error=1, which makes every report fatal.
# Use a build directory of its own (scripts/fuzz.sh uses build-fuzz).
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "MKTREE_BUILD_FUZZERS needs clang for libFuzzer: configure with CC=clang-14 CXX=clang++-14")
endif()
add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer -gline-tables-only)
add_link_options(-fsanitize=address,undefined)
