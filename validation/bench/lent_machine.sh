#!/usr/bin/env bash
# The measurements a lent GPU machine (one GPU, many cores) runs in one call, each part with
# its own time limit so that the call always ends with what it measured:
#   1. the GPU benchmark (validation/bench/gpu.py): with BASE=DIR (a checkout of the code
#      before a change) first that code, then this one, at 1e6 and 2e7 cells, with the
#      warm-start variants of the GPU path (--gpu-warm) and others: the grid's construction,
#      the precision
#      (--gpu-variants: VARIANTS_1E6="host double", VARIANTS_2E7="windows double");
#   1a. on request (PARTS with "elastic"), the elastic pillar (--pillars elastic-pillar) on
#      the GPU against the CPU at 1e6 cells; its compliance is read from $PILLAR_XVAL_CACHE
#      (set it to a carried folder holding the cached one, or it is built there first);
#   1b. an iteration's parts on the GPU at 1e6 cells (validation/bench/gpu_parts.py);
#   2. thread scaling of bem-fft at 1e6 cells on 1 to 16 threads (validation/bench/threads.py);
#   3. the planner's predicted over measured seconds at 1, 4 and 16 threads
#      (validation/bench/planner_threads.py).
# Usage: OUT=DIR [BASE=DIR] [PY=python3] [PARTS="gpu parts threads planner"] [GPU_WARM="1 0"]
#        [VARIANTS_1E6="host"] [VARIANTS_2E7="windows"]
#        [REPEATS_1E6=2] [REPEATS_2E7=1] validation/bench/lent_machine.sh
# The files land in $OUT (at most two folders down, eight files: what a lent machine returns).
set -u
OUT=${OUT:-out/lent-machine}
PY=${PY:-python3}
HERE=$(pwd)
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 PILLAR_XVAL_CACHE=${PILLAR_XVAL_CACHE:-/tmp/pillar-xval-cache}
PARTS=${PARTS:-gpu parts threads planner}
GPU_WARM=${GPU_WARM-1 0}
start=$(date +%s)
has() { case " $PARTS " in *" $1 "*) return 0;; esac; return 1; }
stamp() { echo "== $1 at $(( $(date +%s) - start )) s"; }
{
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
  echo "cpus: $(nproc)"; uname -m
  $PY -c "import sys, numpy, scipy; print(sys.version.split()[0], 'numpy', numpy.__version__, 'scipy', scipy.__version__)"
  $PY -c "import cupy; print('cupy', cupy.__version__)"
} > "$OUT/machine.txt" 2>&1
cat "$OUT/machine.txt"
if has gpu && [ -n "${BASE:-}" ] && [ -d "$BASE" ]; then
  stamp "gpu, before"
  (cd "$BASE" && PYTHONPATH="$BASE" timeout "${T_BEFORE:-100}" $PY -m validation.bench.gpu \
     --out "$OUT/gpu-before" --levels 58 256 --pillars rigid --repeats 1 --cpu-max-cells 2e6)
fi
if has gpu; then
  stamp "gpu, after: 1e6"
  # shellcheck disable=SC2086  # GPU_WARM: a list of variants
  PYTHONPATH="$HERE" timeout "${T_AFTER1:-120}" $PY -m validation.bench.gpu \
    --out "$OUT/gpu-1e6" --levels 58 --repeats "${REPEATS_1E6:-2}" --gpu-warm $GPU_WARM \
    --gpu-variants ${VARIANTS_1E6-}
  stamp "gpu, after: 2e7"
  # shellcheck disable=SC2086
  PYTHONPATH="$HERE" timeout "${T_AFTER2:-80}" $PY -m validation.bench.gpu \
    --out "$OUT/gpu-2e7" --levels 256 --repeats "${REPEATS_2E7:-1}" --cpu-max-cells 2e6 \
    --gpu-warm $GPU_WARM --gpu-variants ${VARIANTS_2E7-}
fi
if has elastic; then
  stamp "elastic pillar: 1e6"
  PYTHONPATH="$HERE" timeout "${T_ELASTIC:-150}" $PY -m validation.bench.gpu \
    --out "$OUT/gpu-elastic" --levels 58 --pillars elastic-pillar --repeats "${REPEATS_1E6:-2}"
fi
if has parts; then
  stamp "parts"
  PYTHONPATH="$HERE" timeout "${T_PARTS:-60}" $PY -m validation.bench.gpu_parts \
    --out "$OUT/parts" --device gpu --n 58 --repeats 20
fi
if has threads; then
  stamp "threads"
  PYTHONPATH="$HERE" timeout "${T_THREADS:-90}" $PY -m validation.bench.threads \
    --out "$OUT/threads" --cases fft --threads 1,2,4,8,16 --repeats 1 --split-threads ""
fi
if has planner; then
  stamp "planner"
  PYTHONPATH="$HERE" timeout "${T_PLANNER:-70}" $PY -m validation.bench.planner_threads \
    --out "$OUT/planner" --threads 1,4,16 --repeats 2
fi
stamp "done"
