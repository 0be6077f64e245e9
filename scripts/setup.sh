#!/usr/bin/env bash
# Fresh machine to working build: install dependencies, configure, build.
# Usage: scripts/setup.sh [extra cmake options]   (build folder: ./build)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
cmake --build build -j"$(nproc)"
