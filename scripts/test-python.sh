#!/usr/bin/env bash
# Runs the Python tests (python/tests, pytest) against the module and CLI of one build (default: ci).
#   scripts/test-python.sh [PRESET]
# Fails when the module was not built or no test is collected (pytest exit code 5).
set -uo pipefail
cd "$(dirname "$0")/.."
preset="${1:-ci}"
build="build/$preset"
if ! ls "$build"/python/rangebayes/_rangebayes*.so >/dev/null 2>&1; then
  echo "test-python: error: $build/python/rangebayes has no _rangebayes module (needs pybind11-dev; run scripts/setup.sh and rebuild)" >&2
  exit 1
fi
export PYTHONPATH="$PWD/$build/python${PYTHONPATH:+:$PYTHONPATH}"
export RANGEBAYES_CLI="$PWD/$build/apps/rangebayes"
export MPLBACKEND=Agg
/usr/bin/python3 -m pytest -q -p no:cacheprovider python/tests
rc=$?
if [ "$rc" -eq 5 ]; then
  echo "test-python: error: pytest collected no tests" >&2
  exit 1
fi
exit "$rc"
