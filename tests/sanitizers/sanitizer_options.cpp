// Default options of the sanitizer runtimes for every executable of a VH_SANITIZE build (the
// top-level CMakeLists.txt adds this file to each one). Compiled-in defaults reach every process
// however it is started: ctest, a test run by hand, the DICOM worker the application spawns, the
// CLI under test. ASAN_OPTIONS / UBSAN_OPTIONS / LSAN_OPTIONS / TSAN_OPTIONS in the environment
// still override them. The suppression files (next to this file) name third-party frames only.
#ifndef VH_SANITIZER_SUPPRESSIONS_DIR
#error "VH_SANITIZER_SUPPRESSIONS_DIR must name tests/sanitizers"
#endif

extern "C" {
// The runtimes look these up as weak symbols; visibility keeps them exported from executables.
__attribute__((visibility("default"), used)) const char* __asan_default_options() {
  // detect_leaks: LeakSanitizer runs at exit (lsan.supp). Uninstrumented VTK / Qt / Mesa keep
  // ODR and container-overflow checks from being meaningful across the boundary, so those two
  // are off; everything else is the default.
  return "detect_leaks=1:abort_on_error=0:halt_on_error=1:detect_odr_violation=0:"
         "detect_container_overflow=0:print_suppressions=0"
#ifdef VH_SANITIZER_CRASH_BOUNDARY
         // volume-haptics-dicom-worker exists to crash in place of the application when
         // vtk-dicom or a VTK mesh reader meets a damaged file: its SIGSEGV / SIGBUS / SIGFPE
         // must end it by that signal (the loader names the signal and the file), not become an
         // ASan report with exit status 1. Memory errors in instrumented code are still reported.
         ":handle_segv=0:handle_sigbus=0:handle_sigfpe=0"
#endif
      ;
}

__attribute__((visibility("default"), used)) const char* __lsan_default_options() {
  return "suppressions=" VH_SANITIZER_SUPPRESSIONS_DIR "/lsan.supp:print_suppressions=0";
}

__attribute__((visibility("default"), used)) const char* __ubsan_default_options() {
  return "print_stacktrace=1:halt_on_error=1:suppressions=" VH_SANITIZER_SUPPRESSIONS_DIR
         "/ubsan.supp";
}

__attribute__((visibility("default"), used)) const char* __tsan_default_options() {
  return "halt_on_error=0:second_deadlock_stack=1:history_size=4:suppressions="
         VH_SANITIZER_SUPPRESSIONS_DIR "/tsan.supp";
}
}  // extern "C"
