#!/usr/bin/env bash
# Make .gpu/ (ignored by git) for tools/gpu/train.sh: what a lent GPU machine, which has no ../shared and
# reaches no registry, needs to train on this checkout's dataset.
#
#   tools/gpu/prepare.sh DATASET_DIR TRAIN_CONFIG [MAX_MB]   (e.g. data/continuum samples/train/continuum/gpu.toml 38)
#
# MAX_MB (default: no limit) bounds the pack: a call to the machine carries 64 MiB in all, the checkout included.
# Every validation sample goes in, then training samples in the order of their ids' hashes (a fixed subset that
# grows with the limit) while the pack stays under it.
#
#   .gpu/train.sgdpack   the dataset's kept training and validation samples (never the test split)
#   .gpu/pairs.tar       the physics pairs' MakeHuman garments and motion-capture clips (tools/gpu/warm_cache.py)
#   .gpu/*.whl           meshio, which the machine's Python lacks
set -euo pipefail
ds=$1
cfg=$2
max_mb=${3:-0}
py=${PYTHON:-.venv/bin/python}
mkdir -p .gpu
links=$(mktemp -d)
mkdir -p "$links/samples" "$links/configs"
cp "$ds"/configs/*.toml "$links/configs/" 2>/dev/null || true
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
n=0
while read -r id; do
  ln -s "$(realpath "$ds/samples/$id.json")" "$links/samples/$id.json"
  ln -s "$(realpath "$ds/samples/$id.npz")" "$links/samples/$id.npz"
  n=$((n + 1))
done <"$links/order.txt"
.venv/bin/segadeform dataset pack "$links" -o .gpu/train.sgdpack --no-rejected
size=$(($(stat -c %s .gpu/train.sgdpack) / 1048576))
if [ "$max_mb" -gt 0 ] && [ "$size" -gt "$max_mb" ]; then
  # keep the prefix of the order that fits: the pack's size is about proportional to the samples' arrays
  keep=$($py - "$links" "$max_mb" "$size" <<'PY'
import os, pathlib, sys
links, limit, size = pathlib.Path(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
ids = (links / "order.txt").read_text().split()
sizes = [os.path.getsize(os.path.realpath(links / "samples" / f"{i}.npz")) for i in ids]
budget = sum(sizes) * limit / size * 0.92
total = k = 0
while k < len(ids) and total + sizes[k] <= budget:
    total += sizes[k]
    k += 1
print(k)
PY
)
  tail -n +"$((keep + 1))" "$links/order.txt" | while read -r id; do rm "$links/samples/$id.json" "$links/samples/$id.npz"; done
  rm .gpu/train.sgdpack
  .venv/bin/segadeform dataset pack "$links" -o .gpu/train.sgdpack --no-rejected
  echo "$keep of $n training and validation samples fit in ${max_mb} MB"
else
  echo "$n training and validation samples"
fi
rm -rf "$links"
pairs=${PAIRS_CACHE:-data/gpu-pairs}  # kept between runs: a second prepare makes nothing again
$py tools/gpu/warm_cache.py "$cfg" "$pairs" --dataset .gpu/train.sgdpack -j "$(nproc)" --pairs-only
(cd "$pairs/cache" && tar cJf - pairs/motions pairs/garments/mh-*) >.gpu/pairs.tar
$py -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform any -d .gpu meshio==5.3.5
du -ch .gpu/* | tail -n 1
