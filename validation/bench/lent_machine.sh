#!/usr/bin/env bash
# The measurements a lent GPU machine (one GPU, many cores) runs in one call, each part with
# its own time limit so that the call always ends with what it measured:
#   1. the GPU benchmark (validation/bench/gpu.py): with BASE=DIR (a checkout of the code
#      before a change) first that code, then this one, at 1e6 and 2e7 cells, with the
#      warm-start variants of the GPU path (--gpu-warm) and others: the grid's construction,
#      the precision
#      (--gpu-variants: VARIANTS_1E6="host double", VARIANTS_2E7="windows double");
#   1a. on request (PARTS with "elastic", run last, with the kit's packages where it is
#      unpacked), the elastic pillar (--pillars elastic-pillar) on the GPU against the CPU at
#      1e6 cells; its compliance is read from $PILLAR_XVAL_CACHE (set it to a carried folder
#      holding the cached one, or it is built there first);
#   1b. an iteration's parts on the GPU at 1e6 cells (validation/bench/gpu_parts.py), with
#      the CG's passes fused and not;
#   1c. on request (PARTS with "first"), where a first call's time goes
#      (validation/bench/gpu_first.py); (PARTS with "tests") the GPU-marked tests, with
#      pytest and array_api_strict carried in .lent/pytest, made here by
#      mkdir -p .lent/pytest && cp -r .venv/lib/python3*/site-packages/{pytest,_pytest,\
#      pluggy,iniconfig,packaging,array_api_strict,py.py} .lent/pytest/;
#   2. thread scaling of bem-fft at 1e6 cells on 1 to 16 threads (validation/bench/threads.py);
#   3. the planner's predicted over measured seconds at 1, 4 and 16 threads
#      (validation/bench/planner_threads.py);
#   4. kit: the fem-3d kit's archives carried in .lent/ unpacked into /tmp/lent-kit, each once
#      (validation/bench/lent_kit.py: two calls, one archive each, fill it);
#   5. fem3d: with the kit (its packages on PYTHONPATH, its MKL and system libraries on
#      LD_LIBRARY_PATH), first its check (gmsh and MKL from the kit, one PARDISO solve),
#      then the thread scaling of fem-3d on paper-fig3-sparse at Phi = FEM3D_PHI (0.82) and
#      mesh_size FEM3D_MESH (2) on FEM3D_THREADS (1,2,4,8,16), its JSON rewritten after
#      each run.
# Usage: OUT=DIR [BASE=DIR] [PY=python3] [PARTS="gpu parts threads planner"] [GPU_WARM="1 0"]
#        [NO_2E7=1: the GPU benchmark at 1e6 only] [CPU_MAX_CELLS=1e5: no CPU column at 1e6]
#        [VARIANTS_1E6="host"] [VARIANTS_2E7="windows"]
#        [REPEATS_1E6=2] [REPEATS_2E7=1] [REPEATS_ELASTIC] [AGAIN=1: GPU solves after the
#        first in each interpreter] [CPU_REPEATS: runs of each CPU case]
#        [FIRST_N="58 256": the first-call profile's levels] [FIRST_PILLARS="rigid"]
#        validation/bench/lent_machine.sh
# The fem-3d kit in two calls: PARTS=kit, carrying .lent/kit-mkl.tar.xz, then
# PARTS="kit fem3d", carrying .lent/kit-gmsh.tar.xz, while the machine is still warm.
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
  echo "cpus: $(nproc)"; uname -m; grep -m1 "model name" /proc/cpuinfo
  $PY -c "import sys, numpy, scipy; print(sys.version.split()[0], 'numpy', numpy.__version__, 'scipy', scipy.__version__)"
  $PY -c "import cupy; print('cupy', cupy.__version__)"
} > "$OUT/machine.txt" 2>&1
cat "$OUT/machine.txt"
KIT_DIR=${KIT_DIR:-/tmp/lent-kit}
kit_env() {
  # MKL's GNU threading layer: the one its runtime picks once gmsh has loaded libgomp.  At
  # most AVX-512: a newer CPU would ask for a kernel library the kit does not carry.
  export PYTHONPATH="$HERE:$KIT_DIR/py" MKL_THREADING_LAYER=GNU \
    MKL_ENABLE_INSTRUCTIONS=AVX512 PYPARDISO_MKL_RT="$KIT_DIR/mkl/libmkl_rt.so.3" \
    LD_LIBRARY_PATH="$KIT_DIR/mkl:$KIT_DIR/sys${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
}
if has kit; then
  stamp "kit"
  PYTHONPATH="$HERE" timeout "${T_KIT:-60}" $PY -m validation.bench.lent_kit unpack \
    --kit .lent --to "$KIT_DIR"
fi
if has tests; then
  # The GPU-marked tests, with pytest and array_api_strict carried in .lent/pytest (the lent
  # machine has neither): the fused CG passes against the array passes, cupy against numpy.
  stamp "tests"
  (  # a subshell: the kit's environment stays out of the parts after it
    # with the kit where it is unpacked (the elastic pillar's tests read its compliance)
    if [ -f "$KIT_DIR/.kit-gmsh.tar.xz.done" ]; then kit_env; fi
    PYTHONPATH="$HERE:$HERE/.lent/pytest${PYTHONPATH:+:$PYTHONPATH}" \
      timeout "${T_TESTS:-120}" $PY -m pytest -q -rs -p no:cacheprovider -m gpu tests/test_cuda_passes.py tests/test_bem_fft_devices.py \
      2>&1 | tail -30 | tee "$OUT/tests.txt"
  )
fi
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
    --gpu-variants ${VARIANTS_1E6-} --cpu-max-cells "${CPU_MAX_CELLS:-2.1e7}" \
    --again "${AGAIN:-1}" ${CPU_REPEATS:+--cpu-repeats "$CPU_REPEATS"}
fi
if has gpu && [ -z "${NO_2E7:-}" ]; then
  stamp "gpu, after: 2e7"
  # shellcheck disable=SC2086
  PYTHONPATH="$HERE" timeout "${T_AFTER2:-80}" $PY -m validation.bench.gpu \
    --out "$OUT/gpu-2e7" --levels 256 --repeats "${REPEATS_2E7:-1}" --cpu-max-cells 2e6 \
    --gpu-warm $GPU_WARM --gpu-variants ${VARIANTS_2E7-} --again "${AGAIN:-1}"
fi
if has parts; then
  stamp "parts"
  PYTHONPATH="$HERE" timeout "${T_PARTS:-60}" $PY -m validation.bench.gpu_parts \
    --out "$OUT/parts" --device gpu --n 58 --repeats 20 --unfused
fi
if has first; then
  for n in ${FIRST_N:-58}; do
    stamp "first call: N = $n"
    PYTHONPATH="$HERE" timeout "${T_FIRST:-90}" $PY -m validation.bench.gpu_first \
      --out "$OUT/first-$n" --n "$n" --pillars ${FIRST_PILLARS:-rigid hooke}
  done
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
if has fem3d && ! { [ -f "$KIT_DIR/.kit-mkl.tar.xz.done" ] \
    && [ -f "$KIT_DIR/.kit-gmsh.tar.xz.done" ]; }; then
  echo "fem3d: the kit in $KIT_DIR is incomplete (a machine given back between the two"
  echo "calls starts bare): carry .lent/kit-mkl.tar.xz and .lent/kit-gmsh.tar.xz again"
elif has fem3d; then
  stamp "fem3d: check"
  kit_env
  if timeout "${T_CHECK:-30}" $PY -m validation.bench.lent_kit check --to "$KIT_DIR" \
      > "$OUT/kit_check.json"; then
    stamp "fem3d: threads ${FEM3D_THREADS:-1,2,4,8,16}"
    timeout "${T_FEM3D:-270}" $PY -m validation.bench.threads --out "$OUT/fem3d" \
      --cases fem3d --fem3d-phi "${FEM3D_PHI:-0.82}" --fem3d-mesh "${FEM3D_MESH:-2}" \
      --threads "${FEM3D_THREADS:-1,2,4,8,16}" --repeats "${FEM3D_REPEATS:-1}" \
      --split-threads ""
  fi
  cat "$OUT/kit_check.json"
fi
if has elastic; then
  # The elastic pillar's compliance is read through fem_reference, which imports scikit-fem:
  # from the kit where it is unpacked.
  stamp "elastic pillar: 1e6"
  if [ -f "$KIT_DIR/.kit-gmsh.tar.xz.done" ]; then kit_env; else export PYTHONPATH="$HERE"; fi
  timeout "${T_ELASTIC:-150}" $PY -m validation.bench.gpu --out "$OUT/gpu-elastic" \
    --levels 58 --pillars elastic-pillar --repeats "${REPEATS_ELASTIC:-${REPEATS_1E6:-2}}" \
    --again "${AGAIN:-1}" ${CPU_REPEATS:+--cpu-repeats "$CPU_REPEATS"}
fi
stamp "done"
