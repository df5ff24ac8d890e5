# Included by the top-level CMakeLists.txt when VH_FUZZ=ON, before any target is defined:
# everything the fuzz targets link (vh::haptics, vh::io, vh::runtime, vh::devices, ...) is built
# with libFuzzer's coverage instrumentation, AddressSanitizer and UndefinedBehaviorSanitizer, so
# the fuzzer is guided through the project's readers and a memory error or UB in them is a
# finding. The system libraries (VTK, vtk-dicom, Qt, zlib) are not instrumented.
# Build only what the targets need: cmake --build build-fuzz --target vh_fuzz_targets
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang" OR NOT CMAKE_C_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "VH_FUZZ=ON needs clang (libFuzzer): configure with "
                      "-DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++")
endif()
# -O1 and assertions on whatever the build type (later options win on clang's command line).
# Line tables only, not full debug information: a sanitizer's stack still names each frame's
# function, file and line (what ci.sh reads to tell the project's code from a system
# library's), and the build compiles and links in less time.
add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
                    -fno-omit-frame-pointer -gline-tables-only -O1 -UNDEBUG)
add_link_options(-fsanitize=address,undefined)
