#!/usr/bin/env bash
# Fuzzes the decode path with libFuzzer, ASan and UBSan, for SECONDS per target (default 60; 0: build only):
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]
# Targets: decode (ParseFile -> Decode -> Rasterize, the CRC-32 as is), decode-crc (the CRC-32 recomputed so
# that mutations reach the payload decoder), io and io-crc (the same two for the ITK entry points:
# DCVImageIO and DCVMeshIO CanReadFile / ReadImageInformation / Read on each input written to a file).
# Builds the ITK-free core with clang in build-fuzz/ (Debian's ITK 5.2 headers refuse clang) and the ITK
# side of the io targets (src/itk/itkDCV*IO.cxx, fuzz/dcvIOFuzzShim.cxx) with g++, seeds each target's corpus
# (build-fuzz/corpus/TARGET, kept between runs) with fuzz/corpus/, and prints libFuzzer's final figures.
# Inputs that crash, hang or exhaust memory are written to build-fuzz/findings/ and the exit status is 1;
# each, once fixed, joins fuzz/corpus/, which the FuzzCorpus test decodes. DCV_FUZZ_JOBS (default 1):
# targets fuzzed at once (the build runs $(nproc) compilations at a time).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --fuzz
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(decode decode-crc io io-crc)

out=build-fuzz
mkdir -p "$out/obj" "$out/include" "$out/findings"
# The export header CMake generates, for a static build of the core.
cat > "$out/include/DelaunayCompressionExport.h.new" <<'H'
#ifndef DelaunayCompression_EXPORT_H
#define DelaunayCompression_EXPORT_H
#define DelaunayCompression_EXPORT
#define DELAUNAYCOMPRESSION_NO_EXPORT
#define DELAUNAYCOMPRESSION_DEPRECATED
#endif
H
cmp -s "$out/include/DelaunayCompressionExport.h.new" "$out/include/DelaunayCompressionExport.h" ||
  mv "$out/include/DelaunayCompressionExport.h.new" "$out/include/DelaunayCompressionExport.h"
rm -f "$out/include/DelaunayCompressionExport.h.new"

# -frounding-math as CGAL's CMake gives gcc: its interval arithmetic switches the rounding mode.
flags=(-std=c++17 -O1 -g -fno-omit-frame-pointer -frounding-math -fsanitize=address,undefined -fno-sanitize-recover=undefined
  -Iinclude -Isrc/core -Isrc/mesh -Isrc/layer -I"$out/include" -isystem /usr/include/eigen3 -DNDEBUG -DCGAL_LINKED_WITH_TBB)
core=(codec/dcvFileFormat codec/dcvCodec codec/dcvArithmeticCoder codec/dcvPositionCoder mesh/dcvApproximation
  mesh/dcvTetrahedralization mesh/dcvTetrahedralize layer/dcvResidualLayer layer/dcvCompactLayer layer/dcvInterSliceWavelet
  layer/dcvVideoLayer layer/dcvVideoHEVC layer/dcvVideoAV1 layer/dcvBoundedLayer)
# What src/itk/itkDCV*IO.cxx need besides: the encoder (DCVImageIO writes too).
encoder=(codec/dcvEncoder codec/dcvBoundedEncoder codec/dcvRateControl mesh/dcvRefinementEngine mesh/dcvDecimation mesh/dcvLeastSquares
  core/dcvPixelSource)
compile() { # SOURCE OBJECT COMPILER FLAGS...: when the source or a header is newer than the object
  local source=$1 object=$2
  shift 2
  if [ ! -f "$object" ] || [ -n "$(find "$source" include src/*/*.h fuzz/*.h -newer "$object" -name '*.[hc]*' | head -1)" ]; then
    echo "$1 $source"
    "$@" -c "$source" -o "$object"
  fi
}
# The compilations run $(nproc) at a time.
compiling=()
compile_later() { # as compile, in the background
  if [ ${#compiling[@]} -ge "$(nproc)" ]; then
    wait "${compiling[0]}"
    compiling=("${compiling[@]:1}")
  fi
  compile "$@" &
  compiling+=($!)
}
objects=()
for s in "${core[@]}"; do
  compile_later "src/$s.cxx" "$out/obj/$(basename "$s").o" clang++ "${flags[@]}" -fsanitize=fuzzer-no-link
  objects+=("$out/obj/$(basename "$s").o")
done
encoder_objects=()
for s in "${encoder[@]}"; do
  compile_later "src/$s.cxx" "$out/obj/$(basename "$s").o" clang++ "${flags[@]}" -fsanitize=fuzzer-no-link
  encoder_objects+=("$out/obj/$(basename "$s").o")
done
# The ITK side, by g++ with ASan and UBSan (its instrumentation calls the ASan and UBSan runtime that clang
# links into the fuzzer; libFuzzer's coverage comes from the clang-built core), at -O0: it is glue around
# the core and ITK's own libraries, and compiles twice as fast (itkDCVEncoderIntegers.cxx: 36 s, 79 at -O1).
itk_flags=(-std=c++17 -O0 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
  -Iinclude -Isrc/core -Isrc/mesh -Isrc/layer -I"$out/include" -Ifuzz -isystem /usr/include/ITK-5.2 -isystem /usr/include/eigen3 -DNDEBUG)
itk_objects=()
# itkDCVEncoder*.cxx: the encoder DCVImageIO::Write calls (itkDCVEncoder.h declares it extern).
for s in src/itk/itkDCVImageIO.cxx src/itk/itkDCVMeshIO.cxx src/itk/itkDCVEncoderIntegers.cxx src/itk/itkDCVEncoderReals.cxx \
  fuzz/dcvIOFuzzShim.cxx; do
  o="$out/obj/$(basename "$s" .cxx).gcc.o"
  compile_later "$s" "$o" g++ "${itk_flags[@]}"
  itk_objects+=("$o")
done
for p in "${compiling[@]}"; do wait "$p"; done
libs=(-lz -lopenjp2 -lx265 -lde265 -laom -ldav1d -ltbb -ltbbmalloc -lgmp -lmpfr -pthread)
itk_libs=(-L/usr/lib -lITKIOMeshBase-5.2 -lITKIOImageBase-5.2 -lITKCommon-5.2 -litkvnl_algo-5.2 -litkvnl-5.2
  -litksys-5.2 -Wl,-rpath,/usr/lib)
link() { # TARGET SOURCE [OPTIONS...]: relinked when the source, a fuzz/ header or an object is newer
  local target="$out/fuzz-$1" source=$2
  shift 2
  if [ ! -f "$target" ] || [ -n "$(find "$source" fuzz/*.h "${objects[@]}" "${encoder_objects[@]}" "${itk_objects[@]}" \
    -newer "$target" | head -1)" ]; then
    echo "link $target"
    clang++ "${flags[@]}" -Ifuzz -fsanitize=fuzzer "$source" "$@" -o "$target"
  fi
}
link decode fuzz/dcvDecodeFuzzer.cxx "${objects[@]}" "${libs[@]}"
link decode-crc fuzz/dcvDecodeFuzzer.cxx -DDCV_FUZZ_FIX_CRC "${objects[@]}" "${libs[@]}"
link io fuzz/dcvIOFuzzer.cxx "${itk_objects[@]}" "${objects[@]}" "${encoder_objects[@]}" "${itk_libs[@]}" "${libs[@]}"
link io-crc fuzz/dcvIOFuzzer.cxx -DDCV_FUZZ_FIX_CRC "${itk_objects[@]}" "${objects[@]}" "${encoder_objects[@]}" \
  "${itk_libs[@]}" "${libs[@]}"

[ "$seconds" -gt 0 ] || exit 0 # 0: build only

run() { # TARGET: fuzzes it; its figures and findings printed when it ends
  local t=$1 rc=0
  mkdir -p "$out/corpus/$t"
  # -timeout: a run over 25 s is a hang; -rss_limit_mb: the decoder's limit (64 MiB) keeps far below it.
  "$out/fuzz-$t" "$out/corpus/$t" fuzz/corpus -max_total_time="$seconds" -timeout=25 -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$out/findings/$t-" >"$out/$t.log" 2>&1 || rc=1
  {
    echo "== $t: $seconds s"
    grep -E "^#[0-9]+[[:space:]]+DONE|stat::number_of_executed_units|stat::slowest_unit_time_sec|stat::peak_rss_mb|ERROR|SUMMARY" \
      "$out/$t.log" || true
  } | sed "s/^/[$t] /"
  return $rc
}
status=0
jobs=${DCV_FUZZ_JOBS:-1}
running=0
for t in "${targets[@]}"; do
  [ -x "$out/fuzz-$t" ] || { echo "unknown target: $t" >&2; exit 2; }
  if [ "$running" -ge "$jobs" ]; then
    wait -n || status=1
    running=$((running - 1))
  fi
  run "$t" &
  running=$((running + 1))
done
while [ "$running" -gt 0 ]; do
  wait -n || status=1
  running=$((running - 1))
done
# A slow unit (over 10 s, -report_slow_units) is kept for a look but is no failure on a loaded machine; a
# timeout (25 s), crash, leak or out-of-memory is.
for f in "$out"/findings/*; do
  [ -e "$f" ] || continue
  case "$f" in
  *-slow-unit-*) echo "slow input (not a failure): $f" ;;
  *) echo "finding: $f" ;;
  esac
done
exit $status
