#!/usr/bin/env bash
# Fuzzes the decode path (ParseFile -> Decode -> Rasterize) with libFuzzer, ASan and UBSan, for SECONDS
# per target (default 60; 0: build only):
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]      targets: decode (CRC-32 as is), decode-crc (recomputed)
# Builds the ITK-free core with clang in build-fuzz/ (Debian's ITK 5.2 headers refuse clang), seeds each
# target's corpus (build-fuzz/corpus/TARGET, kept between runs) with fuzz/corpus/, and prints libFuzzer's
# final figures. Inputs that crash, hang or exhaust memory are written to build-fuzz/findings/; each becomes
# a regression test (test/fuzz-findings/ and dcvResourceLimitsTest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --fuzz
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(decode decode-crc)

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

flags=(-std=c++17 -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
  -Iinclude -I"$out/include" -DNDEBUG)
core=(dcvFileFormat dcvCodec dcvArithmeticCoder dcvPositionCoder dcvApproximation dcvTetrahedralization
  dcvResidualLayer)
objects=()
for s in "${core[@]}"; do
  o="$out/obj/$s.o"
  if [ ! -f "$o" ] || [ -n "$(find src/$s.cxx include -newer "$o" -name '*.[hc]*' | head -1)" ]; then
    echo "clang++ src/$s.cxx"
    clang++ "${flags[@]}" -fsanitize=fuzzer-no-link -c "src/$s.cxx" -o "$o"
  fi
  objects+=("$o")
done
libs=(-lz -lopenjp2 -ltbb -lgmp -lmpfr -pthread)
link() { # TARGET [DEFINES...]: relinked when the fuzzer or an object is newer
  local target="$out/fuzz-$1"
  shift
  if [ ! -f "$target" ] || [ -n "$(find fuzz/dcvDecodeFuzzer.cxx "${objects[@]}" -newer "$target" | head -1)" ]; then
    echo "link $target"
    clang++ "${flags[@]}" -fsanitize=fuzzer "$@" fuzz/dcvDecodeFuzzer.cxx "${objects[@]}" "${libs[@]}" -o "$target"
  fi
}
link decode
link decode-crc -DDCV_FUZZ_FIX_CRC

[ "$seconds" -gt 0 ] || exit 0 # 0: build only

status=0
for t in "${targets[@]}"; do
  mkdir -p "$out/corpus/$t"
  echo "== $t: $seconds s"
  # -timeout: a run over 25 s is a hang; -rss_limit_mb: the decoder's limit (64 MiB) keeps far below it.
  "$out/fuzz-$t" "$out/corpus/$t" fuzz/corpus -max_total_time="$seconds" -timeout=25 -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$out/findings/$t-" >"$out/$t.log" 2>&1 || status=1
  grep -E "^#[0-9]+ +DONE|stat::number_of_executed_units|stat::peak_rss_mb|ERROR|SUMMARY" "$out/$t.log" || true
  tail -n 1 "$out/$t.log"
done
ls "$out/findings" | sed 's/^/finding: /'
exit $status
