#!/usr/bin/env bash
# The main job on bundled data (README command 1). Results go to out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/release/apps/rangebayes
mkdir -p out/demo
"$bin" --help
