#!/usr/bin/env bash
# The files `dcv compress VOLUME OUT --bpv R` writes for every dev volume (../shared/data) at 0.03125,
# 0.0625, 0.125 and 0.25 bpv, one md5 a line: run before and after a change that must not change the
# files (a refactoring, a speed-up), and compare the two outputs with diff.
# Usage: bash scripts/dev_checksums.sh [DCV] > sums.txt   (DCV: default build/tools/dcv/dcv)
# About 6 minutes on 2 cores (norm-256 at 0.25 bpv is most of it).
set -euo pipefail
cd "$(dirname "$0")/.."
dcv=$(realpath "${1:-build/tools/dcv/dcv}")
data=../shared/data
if [ ! -d "$data" ]; then
  echo "dev_checksums: $data is absent; nothing to check" >&2
  exit 0
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for volume in "$data"/*.nrrd "$data"/dicom-ct-brain-5mm; do
  name=$(basename "$volume" .nrrd)
  for rate in 0.03125 0.0625 0.125 0.25; do
    "$dcv" compress "$volume" "$work/$name-$rate.dcv" --bpv "$rate" --force >/dev/null 2>&1 \
      || { echo "$name $rate FAILED"; continue; }
    echo "$name $rate $(md5sum < "$work/$name-$rate.dcv" | cut -d' ' -f1)"
  done
done
