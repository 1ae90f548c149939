#!/usr/bin/env bash
# Builds the module, runs the whole test suite, then installs it and builds examples/ against the
# installed CMake package, as another project would.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS
bash scripts/build.sh
echo "build: $((SECONDS - start)) s"
test_start=$SECONDS
(cd build && ctest --output-on-failure -j "$(nproc)")
echo "tests: $((SECONDS - test_start)) s"
examples_start=$SECONDS
rm -rf build/install build/examples
cmake --install build >/dev/null
cmake -S examples -B build/examples -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$PWD/build/install" >/dev/null
cmake --build build/examples

mkdir -p build/examples/run
build/tools/dcv/dcv phantom build/examples/run/phantom.nrrd --size 48 --force
build/examples/ApproximateVolume build/examples/run/phantom.nrrd build/examples/run/approximation.nrrd 2000
build/examples/WriteReadDCV build/examples/run/phantom.nrrd build/examples/run/phantom.dcv 0.125
build/examples/ReadDCVImage build/examples/run/phantom.dcv build/examples/run/phantom-decoded.nrrd
build/examples/DecodeDCVRegion build/examples/run/phantom.dcv build/examples/run/slab.nrrd 20 27
build/examples/ReadDCVMesh build/examples/run/phantom.dcv
echo "examples: $((SECONDS - examples_start)) s"
