#!/usr/bin/env bash
# Benchmarks the encoder and the decoder on the shared real volumes and prints one Markdown table.
#
# Usage: scripts/benchmark.sh [VOLUME.nrrd ...]
#   With no arguments, every *.nrrd in ../shared/data (relative to the repository root); otherwise only
#   the named files of that directory. Point counts come from DCV_BENCH_POINTS (default
#   "1000 3000 10000 30000"). Build output goes to stderr, the table to stdout.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
data="${root}/../shared/data"
read -r -a points <<<"${DCV_BENCH_POINTS:-1000 3000 10000 30000}"

if [[ ! -d "${data}" ]]; then
  echo "benchmark.sh: no data directory at ${data}; nothing to benchmark" >&2
  exit 0
fi

volumes=()
if (($# > 0)); then
  for name in "$@"; do
    if [[ ! -f "${data}/${name}" ]]; then
      echo "benchmark.sh: no volume '${name}' in ${data}" >&2
      exit 1
    fi
    volumes+=("${data}/${name}")
  done
else
  shopt -s nullglob
  volumes=("${data}"/*.nrrd)
  shopt -u nullglob
  if ((${#volumes[@]} == 0)); then
    echo "benchmark.sh: no *.nrrd volumes in ${data}; nothing to benchmark" >&2
    exit 0
  fi
fi

cd "${root}"
# Configure only once; ninja itself re-runs CMake when a CMakeLists.txt changes.
if [[ ! -f build/build.ninja ]]; then
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >&2
fi
ninja -C build dcvBenchmark >&2

# One process per volume, so that the peak memory column belongs to that volume alone.
header=()
for volume in "${volumes[@]}"; do
  build/benchmark/dcvBenchmark "${header[@]+"${header[@]}"}" "${volume}" "${points[@]}"
  header=(--no-header)
done
