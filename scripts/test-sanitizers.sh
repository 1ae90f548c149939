#!/usr/bin/env bash
# CI's second build (.ci/run, after scripts/test.sh): the test suite (all but three heavy tests, below) built
# with AddressSanitizer (and LeakSanitizer) and UndefinedBehaviorSanitizer (gcc; line tables, any undefined
# behaviour fatal; the library and tools/common at -O1, the programs and tests, ITK glue, at -O0: they
# compile faster) in build-asan/, run
# by ctest; the decoder of build/ (scripts/test.sh) under valgrind on the fuzz seeds; then a short libFuzzer
# run of every fuzz target (scripts/fuzz.sh, DCV_CI_FUZZ_SECONDS per target, default 30; 0 skips it). Fails
# on any sanitizer report, in the tests or in the programs they run, even where a test expected its program
# to fail: every report goes to build-asan/sanitizer-reports/, which must stay empty. Not built: the
# benchmarks (no test runs them); the wrapping check compiles two pixel types instead of ten (the normal
# build compiles them all; here its test only runs what it creates).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
start=$SECONDS

cmake -S . -B build-asan -G Ninja -DDCV_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DDelaunayCompression_BUILD_BENCHMARKS=OFF -DDelaunayCompression_WRAP_CHECK_TYPES="UC;F" \
  -DDelaunayCompression_PROGRAM_COMPILE_OPTIONS=-O0 >/dev/null
cmake --build build-asan -j "$(nproc)"
echo "sanitizer build: $((SECONDS - start)) s"

reports="$PWD/build-asan/sanitizer-reports"
rm -rf "$reports"
mkdir -p "$reports"
supp="$PWD/test/sanitizers"
# A report aborts the process (halt_on_error) and is written to $reports/KIND.PID, not to the output a
# test may compare.
# max_malloc_fill_size: ASan fills every block it hands out, as glibc's perturbation does in the Release
# build (x265 3.5 reads heap memory it never wrote; src/layer/dcvVideoHEVC.cxx), so that the tests of the
# same stream every time hold here too (ASan fills only the first 4 KiB by default).
export ASAN_OPTIONS="halt_on_error=1:abort_on_error=1:detect_leaks=1:check_initialization_order=1:strict_init_order=1:detect_stack_use_after_return=1:max_malloc_fill_size=2147483647:log_path=$reports/asan"
export UBSAN_OPTIONS="halt_on_error=1:abort_on_error=1:print_stacktrace=1:log_path=$reports/ubsan:suppressions=$supp/ubsan.supp"
export LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0"
# Not run here, for time: the tests that check a result's quality or agreement on real data, each with a
# cheaper test of the same code paths that does run (in parentheses). scripts/test.sh runs them in Release.
# The dev volumes' runs (every volume of ../shared/data) were 564 of the 1,915 CPU-seconds of this step's
# tests; the other three 155 of 837 before them.
heavy=(
  'DevVolumes/.*'                                         # (CommandLine.CompressDecompressInfo, BoundedLayer.*)
  'Encoder.MeetsAPSNRTargetWithFewPoints'                 # (CommandLine.CompressToAPSNRTarget)
  'DCVImageIO.ImageFileWriterWritesWhatTheToolWrites'     # (DCVImageIO.ImageFileWriterWritesRealCTAsTheToolDoes)
  'PositionCoder.RealPointSetsCostLessThanRandomOnes'     # (PositionCoder.RandomSetsOfManyDensities)
)
exclude="^($(IFS='|'; echo "${heavy[*]}"))\$"
test_start=$SECONDS
status=0
(cd build-asan && ctest --output-on-failure -j "$(nproc)" -E "$exclude") || status=1
echo "sanitizer tests: $((SECONDS - test_start)) s"
if [ -n "$(ls -A "$reports")" ]; then
  for f in "$reports"/*; do
    echo "== $f"
    cat "$f"
  done
  echo "sanitizer reports: $(ls "$reports" | wc -l)"
  status=1
fi
[ $status -eq 0 ] || exit $status

# The decoder under valgrind (memcheck), the Release build of scripts/test.sh: every seed of fuzz/corpus
# decoded to voxels (dcv decompress) and to a mesh (dcv mesh). The whole test suite under valgrind would
# take hours; ASan covers it above.
if [ -x build/tools/dcv/dcv ]; then
  command -v valgrind >/dev/null || {
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo=sudo
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends valgrind >/dev/null
  }
  valgrind_start=$SECONDS
  out=build/valgrind
  rm -rf "$out"
  mkdir -p "$out"
  memcheck() { # LOG ARGUMENTS...: dcv ARGUMENTS under valgrind, its output in LOG; false on an error
    local log=$1
    shift
    valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=definite build/tools/dcv/dcv "$@" \
      >"$log" 2>&1 || { echo "valgrind: dcv $*" && cat "$log" && return 1; }
  }
  # Each run is one single-threaded process, most of it valgrind starting ITK: $(nproc) at a time.
  pids=()
  for f in fuzz/corpus/*.dcv; do
    n=$(basename "$f" .dcv)
    for run in "decompress $f $out/$n.nrrd" "mesh $f $out/$n.vtu"; do
      if [ ${#pids[@]} -ge "$(nproc)" ]; then
        wait "${pids[0]}" || status=1
        pids=("${pids[@]:1}")
      fi
      memcheck "$out/$n-${run%% *}.log" $run &
      pids+=($!)
    done
  done
  for p in "${pids[@]}"; do wait "$p" || status=1; done
  echo "valgrind (dcv decompress and mesh on $(ls fuzz/corpus/*.dcv | wc -l) files): $((SECONDS - valgrind_start)) s"
  [ $status -eq 0 ] || exit $status
fi

fuzz_seconds=${DCV_CI_FUZZ_SECONDS:-30}
if [ "$fuzz_seconds" -gt 0 ]; then
  fuzz_start=$SECONDS
  unset ASAN_OPTIONS UBSAN_OPTIONS LSAN_OPTIONS
  rm -rf build-fuzz/findings
  DCV_FUZZ_JOBS="$(nproc)" bash scripts/fuzz.sh "$fuzz_seconds"
  echo "fuzzing (build and run): $((SECONDS - fuzz_start)) s"
fi
