#!/usr/bin/env bash
# Issue 37's measurement on a lent GPU machine (docs/gpu.md "Measuring"): run from the repository
# root there, with the wheels of `make device-wheels` carried in .whl/. The machine's image has
# Python 3.12, numba, numba-cuda and CUDA 13, but numpy 2.5, with which numba-cuda 0.30.4 does not
# import (np.row_stack): numpy 2.4, numba-cuda 0.30.4 and what refexmc needs beyond the image go to
# /tmp/site, ahead of the image's packages. refexmc itself runs from this checkout (pure Python).
#   bash benchmarks/gpu_device.sh [bench_gpu.py options]      (results: $OUT/bench_gpu.json)
set -euo pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
export PYTHONPATH="/tmp/site:$PWD" PYTHONUNBUFFERED=1 XDG_CACHE_HOME=/tmp/refexmc-cache
python3 - <<'PY'
import numba, numpy
from numba import cuda
print("numpy", numpy.__version__, "numba", numba.__version__, "cuda available", cuda.is_available())
cuda.detect()
PY
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
# the GPU backend's launches take at most a quarter of the host's available memory (docs/gpu.md)
grep -E "MemTotal|MemAvailable" /proc/meminfo || true
# the campaigns (~17 GB at 10^6 runs with histories) stay on the machine; only the JSON comes back
python3 benchmarks/bench_gpu.py --work /tmp/bench_gpu --json "${OUT:-.}/bench_gpu.json" "$@"
