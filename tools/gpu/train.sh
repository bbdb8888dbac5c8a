#!/usr/bin/env bash
# Train several configs side by side on a lent CUDA machine within one command's time limit, and leave
# their run folders in $OUT/runs.tgz.  The machine needs no ../shared: the training samples come as a pack
# and the physics pairs' garments and motion clips as a cache made beside the checkout (tools/gpu/README.md).
#
#   tools/gpu/train.sh DEADLINE_SECONDS DEVICE CONFIG...      (DEVICE: cuda, or cpu to rehearse it here)
#   tools/gpu/train.sh DEADLINE_SECONDS stage CONFIG          (a first call: install, unpack, warm the cache, stop)
#
# Every pack in .gpu/ and .gpu2/ is trained on.  A call carries 64 MiB in all, so a dataset larger than one call
# holds comes in two: the first carries .gpu/ (the pairs and the first pack) and stages it (the machine keeps
# what the first call left while it stays warm), the second carries .gpu2/ (the second pack) and trains.
# Inputs in .gpu/ (ignored by git): train.sgdpack (the training and validation samples), pairs.tar (the
# cache's pairs/: garments, their precompute, motion clips) and the wheels the machine lacks (*.whl).
set -u
start=$(date +%s)
deadline=$1
device=$2
shift 2
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=2
out=${OUT:-/tmp/gpu-out}
work=${GPU_WORK:-.}  # where runs/ is made (a rehearsal here: another folder than the checkout's runs/)
mkdir -p "$out"
say() { echo "[$(($(date +%s) - start)) s] $*"; }
py=python3
cli='import sys; from segadeform.cli.main import main; sys.exit(main())'  # the command, wherever pip put its script
command -v nvidia-smi >/dev/null && nvidia-smi -L
if ! $py -c "import segadeform" 2>/dev/null; then
  $py -m pip install -q --no-index --no-deps .gpu/*.whl 2>&1 | tail -n 2
  $py -m pip install -q --no-index --no-deps --no-build-isolation -e . 2>&1 | tail -n 2
fi
$py -c "import segadeform, torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available())" || exit 1
ds=${GPU_DS:-/tmp/gpu-ds}
mkdir -p "$ds/samples" "$ds/cache"
[ -f .gpu/pairs.tar ] && [ ! -d "$ds/cache/pairs/motions" ] && tar xf .gpu/pairs.tar -C "$ds/cache"
packs=()
for p in .gpu/*.sgdpack .gpu2/*.sgdpack; do [ -f "$p" ] && packs+=(--dataset "$p"); done
[ "${#packs[@]}" -eq 0 ] && { say "no pack in .gpu/ or .gpu2/"; exit 1; }
say "packs: ${packs[*]}"
say "warming the cache"
$py tools/gpu/warm_cache.py "$1" "$ds" "${packs[@]}" -j "$(nproc)" || exit 1
if [ "$device" = stage ]; then say "staged"; exit 0; fi
mkdir -p "$work/runs"
run_all() {  # run_all DEVICE SECONDS CONFIG...: every config side by side, in the background
  local dev=$1 secs=$2
  shift 2
  pids=()
  for cfg in "$@"; do
    name=$(basename "$cfg" .toml)
    $py -c "$cli" train "$cfg" -o "$work/runs/$name" --dataset "$ds" "${packs[@]}" --device "$dev" \
      --seconds "$secs" --threads 2 >"$work/runs/$name.log" 2>&1 &
    pids+=($!)
  done
}
left=$((start + deadline - $(date +%s)))
secs=$((left - 40))  # a run's budget holds its loading; the final save and packing take the rest
if [ "$secs" -lt 60 ]; then say "only ${secs} s left for training: stopping"; exit 1; fi
say "training $# configs on $device for ${secs} s each"
run_all "$device" "$secs" "$@"
fallback=0
declare -A code=()
while :; do
  sleep 5
  alive=0
  for p in "${pids[@]}"; do
    if [ -n "${code[$p]:-}" ]; then continue; fi
    if kill -0 "$p" 2>/dev/null; then alive=$((alive + 1)); else wait "$p"; code[$p]=$?; fi
  done
  failed=0
  for p in "${pids[@]}"; do [ "${code[$p]:-0}" -ne 0 ] && failed=$((failed + 1)); done
  now=$(date +%s)
  if [ "$alive" -eq 0 ]; then
    if [ "$failed" -eq "$#" ] && [ "$device" != cpu ] && [ "$fallback" -eq 0 ]; then
      say "every run failed on $device:"; tail -n 5 "$work"/runs/*.log
      fallback=1
      secs=$((start + deadline - now - 40))
      [ "$secs" -lt 60 ] && break
      mkdir -p "$work/runs-failed-$device" && mv "$work"/runs/* "$work/runs-failed-$device/"
      say "training on cpu for ${secs} s instead"
      device=cpu
      code=()
      run_all cpu "$secs" "$@"
      continue
    fi
    break
  fi
  if [ "$now" -gt $((start + deadline - 15)) ]; then
    # (background jobs of a script ignore SIGINT: TERM; a stopped run keeps its best.pt and last.pt)
    say "deadline: stopping $alive runs"; kill -TERM "${pids[@]}" 2>/dev/null; sleep 3; break
  fi
done
for f in "$work"/runs/*.log; do echo "== $f"; tail -n 3 "$f"; done
# a finished run's last.pt (weights and optimiser state) stays behind: what comes back is bounded (16 MiB a file)
for d in "$work"/runs/*/; do [ -f "$d/model.pt" ] && rm -f "$d/last.pt"; done
tar czf "$out/runs.tgz" -C "$work" runs $(cd "$work" && ls -d runs-failed-* 2>/dev/null)
say "done: $(du -h "$out/runs.tgz" | cut -f1)"
