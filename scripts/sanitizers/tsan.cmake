# Initial CMake cache (cmake -C) for the ThreadSanitizer build of the DDS packages, used by
# scripts/sanitize.sh. See asan.cmake for why the flags sit in the Release variables.
set(CMAKE_C_COMPILER clang CACHE STRING "")
set(CMAKE_CXX_COMPILER clang++ CACHE STRING "")
set(CMAKE_C_FLAGS_RELEASE "-O1 -gline-tables-only -DNDEBUG -fsanitize=thread -fno-omit-frame-pointer" CACHE STRING "")
set(CMAKE_CXX_FLAGS_RELEASE "-O1 -gline-tables-only -DNDEBUG -fsanitize=thread -fno-omit-frame-pointer" CACHE STRING "")
set(CMAKE_EXE_LINKER_FLAGS "-fsanitize=thread" CACHE STRING "")
set(CMAKE_SHARED_LINKER_FLAGS "-fsanitize=thread" CACHE STRING "")
set(CMAKE_MODULE_LINKER_FLAGS "-fsanitize=thread" CACHE STRING "")
