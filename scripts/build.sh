#!/usr/bin/env bash
# Configures and builds the module in build/ (Release). Used by demo.sh and test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$PWD/build/install" >/dev/null
cmake --build build -j "$(nproc)" # ninja alone would run nproc + 2 heavy compilations
