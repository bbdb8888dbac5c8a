#!/usr/bin/env bash
# Make .gpu/ (ignored by git) for tools/gpu/train.sh: what a lent GPU machine, which has no ../shared and
# reaches no registry, needs to train on this checkout's dataset.
#
#   tools/gpu/prepare.sh DATASET_DIR TRAIN_CONFIG [MAX_MB [MAX2_MB]]   (e.g. data/continuum samples/train/continuum/gpu.toml 38 48)
#
# MAX_MB (default: no limit) bounds the pack: a call to the machine carries 64 MiB in all, the checkout included.
# MAX2_MB puts the samples that do not fit into a second pack, .gpu2/train2.sgdpack, for a second call.
# Every validation sample goes in, then training samples in the order of their ids' hashes (a fixed subset that
# grows with the limit) while the pack stays under it.
#
#   .gpu/train.sgdpack   the dataset's kept training and validation samples (never the test split)
#   .gpu/pairs.tar       the physics pairs' MakeHuman garments and motion-capture clips (tools/gpu/warm_cache.py)
#   .gpu/*.whl           meshio, which the machine's Python lacks
set -euo pipefail
shopt -s inherit_errexit  # a failure inside $(...) stops the script too
ds=$1
cfg=$2
max_mb=${3:-0}
max2_mb=${4:-0}
py=${PYTHON:-.venv/bin/python}
mkdir -p .gpu
links=$(mktemp -d)
# validation samples first, then training samples by the hash of their ids
$py - "$ds" >"$links/order.txt" <<'PY'
import hashlib, json, pathlib, sys
rows = []
for j in sorted(pathlib.Path(sys.argv[1], "samples").glob("*.json")):
    split = json.loads(j.read_text()).get("split")
    if split in ("train", "val"):
        rows.append((split != "val", hashlib.sha256(j.stem.encode()).hexdigest(), j.stem))
print("\n".join(r[2] for r in sorted(rows)))
PY
rm -f .gpu/train.sgdpack
rm -rf .gpu2
n=$(wc -l <"$links/order.txt")
# the prefix of the order that fits in MAX_MB goes to .gpu/, the next MAX2_MB to .gpu2/; a pack's size is about
# proportional to its samples' arrays, and a pack over its limit is made again from an estimate 8 % larger per
# sample (so fewer of them)
pack_part() {  # pack_part FIRST LIMIT_MB OUT: pack samples FIRST.. of the order within LIMIT_MB; prints the count
  local first=$1 limit=$2 outp=$3 scale=0.075 k
  while :; do
    k=$($py - "$links" "$ds" "$first" "$limit" "$scale" <<'PY'
import os, pathlib, sys
links, ds, first, limit, scale = pathlib.Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5])
ids = (links / "order.txt").read_text().split()[first:]
total = k = 0
while k < len(ids) and (limit <= 0 or total + scale * os.path.getsize(f"{ds}/samples/{ids[k]}.npz") <= limit * 1048576):
    total += scale * os.path.getsize(f"{ds}/samples/{ids[k]}.npz")
    k += 1
print(k)
PY
)
    [ -n "$k" ] || return 1
    if [ "$k" -eq 0 ]; then rm -f "$outp"; echo 0; return; fi
    rm -rf "$links/part"
    mkdir -p "$links/part/samples" "$links/part/configs"
    cp "$ds"/configs/*.toml "$links/part/configs/" 2>/dev/null || true
    tail -n +"$((first + 1))" "$links/order.txt" | head -n "$k" | while read -r id; do
      ln -s "$(realpath "$ds/samples/$id.json")" "$links/part/samples/$id.json"
      ln -s "$(realpath "$ds/samples/$id.npz")" "$links/part/samples/$id.npz"
    done
    rm -f "$outp"
    .venv/bin/segadeform dataset pack "$links/part" -o "$outp" --no-rejected >&2 || return 1
    [ -f "$outp" ] || return 1
    if [ "$limit" = 0 ] || [ "$(stat -c %s "$outp")" -le $((limit * 1048576)) ]; then echo "$k"; return; fi
    scale=$($py -c "print($scale * 1.08)")
  done
}
[ "$n" -gt 0 ] && [ -n "$(head -c 1 "$links/order.txt" | tr -d '\n')" ] || { echo "$ds: no training or validation sample" >&2; exit 1; }
k1=$(pack_part 0 "$max_mb" .gpu/train.sgdpack)
[ "$k1" -gt 0 ] || { echo "not one sample fits in ${max_mb} MB" >&2; exit 1; }
echo "$k1 of $n training and validation samples in .gpu/train.sgdpack"
if [ "$k1" -lt "$n" ] && [ "${max2_mb:-0}" -gt 0 ]; then
  mkdir -p .gpu2
  k2=$(pack_part "$k1" "$max2_mb" .gpu2/train2.sgdpack)
  echo "$k2 more in .gpu2/train2.sgdpack (carried by a second call: tools/gpu/README.md)"
  left=$((n - k1 - k2))
  [ "$left" -gt 0 ] && echo "$left samples fit in neither pack: left out" >&2
elif [ "$k1" -lt "$n" ]; then
  echo "$((n - k1)) samples do not fit in ${max_mb} MB: left out (MAX2_MB puts them into a second pack)" >&2
fi
rm -rf "$links"
pairs=${PAIRS_CACHE:-data/gpu-pairs}  # kept between runs: a second prepare makes nothing again
$py tools/gpu/warm_cache.py "$cfg" "$pairs" --dataset .gpu/train.sgdpack -j "$(nproc)" --pairs-only
(cd "$pairs/cache" && tar cJf - pairs/motions pairs/garments/mh-*) >.gpu/pairs.tar
$py -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform any -d .gpu meshio==5.3.5
du -ch .gpu/* | tail -n 1
