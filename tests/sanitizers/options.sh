# Sanitizer run-time options for the build-asan tree, sourced by tools/run-sanitized.sh and tools/fuzz.sh.
# Expects $root (the source tree).
sanitizers="$root/tests/sanitizers"
# Reports name functions and lines only through a symbolizer; Debian's llvm-14 puts it off PATH.
if [ -z "${ASAN_SYMBOLIZER_PATH:-}" ] && [ -x /usr/lib/llvm-14/bin/llvm-symbolizer ]; then
  export ASAN_SYMBOLIZER_PATH=/usr/lib/llvm-14/bin/llvm-symbolizer
fi
# exitcode: a report must never pass for the CLI's own failure statuses (1 runtime, 2 bad input).
# check_initialization_order/strict_init_order: static initialisers across the project's libraries.
export ASAN_OPTIONS="exitcode=99:halt_on_error=1:detect_leaks=1:check_initialization_order=1:strict_init_order=1:strict_string_checks=1"
export UBSAN_OPTIONS="exitcode=99:halt_on_error=1:print_stacktrace=1:suppressions=$sanitizers/ubsan.supp"
export LSAN_OPTIONS="exitcode=99:suppressions=$sanitizers/lsan.supp"
