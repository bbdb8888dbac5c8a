#!/usr/bin/env bash
# Make .gpu/ (ignored by git) for tools/gpu/train.sh: what a lent GPU machine, which has no ../shared and
# reaches no registry, needs to train on this checkout's dataset.
#
#   tools/gpu/prepare.sh DATASET_DIR TRAIN_CONFIG      (e.g. data/continuum samples/train/continuum/gpu.toml)
#
#   .gpu/train.sgdpack   the dataset's kept training and validation samples (never the test split)
#   .gpu/pairs.tar       the physics pairs' MakeHuman garments and motion-capture clips (tools/gpu/warm_cache.py)
#   .gpu/*.whl           meshio, which the machine's Python lacks
set -euo pipefail
ds=$1
cfg=$2
py=${PYTHON:-.venv/bin/python}
mkdir -p .gpu
links=$(mktemp -d)
mkdir -p "$links/samples" "$links/configs"
cp "$ds"/configs/*.toml "$links/configs/" 2>/dev/null || true
n=0
for j in "$ds"/samples/*.json; do
  split=$($py -c "import json,sys; print(json.load(open(sys.argv[1])).get('split'))" "$j")
  if [ "$split" = train ] || [ "$split" = val ]; then
    id=$(basename "$j" .json)
    ln -s "$(realpath "$j")" "$links/samples/$id.json"
    ln -s "$(realpath "$ds/samples/$id.npz")" "$links/samples/$id.npz"
    n=$((n + 1))
  fi
done
echo "$n training and validation samples"
rm -f .gpu/train.sgdpack
.venv/bin/segadeform dataset pack "$links" -o .gpu/train.sgdpack --no-rejected
rm -rf "$links"
pairs=${PAIRS_CACHE:-data/gpu-pairs}  # kept between runs: a second prepare makes nothing again
$py tools/gpu/warm_cache.py "$cfg" "$pairs" --dataset .gpu/train.sgdpack -j "$(nproc)" --pairs-only
(cd "$pairs/cache" && tar cJf - pairs/motions pairs/garments/mh-*) >.gpu/pairs.tar
$py -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform any -d .gpu meshio==5.3.5
du -ch .gpu/* | tail -n 1
