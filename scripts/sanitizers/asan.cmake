# Initial CMake cache (cmake -C) for the ASan+UBSan build of the workspace, used by
# scripts/sanitize.sh through `colcon build --cmake-args -C <this file>`.
#
# clang, not gcc: the same build serves the libFuzzer targets (fuzz/), which need clang, so CI
# compiles the workspace once for both. -fsanitize=fuzzer-no-link only adds coverage counters
# to the project's code (libFuzzer itself is linked into the fuzz targets alone); tests run with
# the sanitizer runtime's no-op coverage callbacks.
#
# colcon.meta appends -DCMAKE_BUILD_TYPE=Release for every package, so the flags go into the
# Release variables: -O1 keeps instrumented compiles fast and stack traces exact; NDEBUG stays
# so the tests exercise the same code paths as the Release build. -gline-tables-only: reports keep
# file:line for every frame; full -g cost 11 % more compile time on lio_ppf.cpp and 5x the object
# size (27 vs 5 MB), for variable info nobody reads in CI logs.
set(CMAKE_C_COMPILER clang CACHE STRING "")
set(CMAKE_CXX_COMPILER clang++ CACHE STRING "")
set(PPF_SANITIZE_FLAGS
    "-fsanitize=address,undefined,fuzzer-no-link -fno-sanitize-recover=all -fno-omit-frame-pointer")
set(CMAKE_C_FLAGS_RELEASE "-O1 -gline-tables-only -DNDEBUG ${PPF_SANITIZE_FLAGS}" CACHE STRING "")
set(CMAKE_CXX_FLAGS_RELEASE "-O1 -gline-tables-only -DNDEBUG ${PPF_SANITIZE_FLAGS}" CACHE STRING "")
# Shared libraries stay undefined-symbol tolerant (the runtime lives in the executable).
set(CMAKE_EXE_LINKER_FLAGS "-fsanitize=address,undefined" CACHE STRING "")
set(CMAKE_SHARED_LINKER_FLAGS "-fsanitize=address,undefined" CACHE STRING "")
set(CMAKE_MODULE_LINKER_FLAGS "-fsanitize=address,undefined" CACHE STRING "")
set(PPF_FUZZ ON CACHE BOOL "build the libFuzzer targets in fuzz/")
