#!/usr/bin/env bash
# `make demo`: one replayed trial on real GelSight recordings, printing its answer.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
DATA=""
for d in "${TACTEX_SHARED:-}/datasets/octopi-dev" "$ROOT/../shared/datasets/octopi-dev" /work/shared/datasets/octopi-dev; do
  if [ -d "$d" ]; then DATA=$d; break; fi
done
mkdir -p runs
if [ -n "$DATA" ]; then
  SOURCE="replay:$DATA"
else
  echo "octopi-dev recordings not found; using the fabric simulator" >&2
  SOURCE="sim:medium"
fi
exec .venv/bin/tactex trial --source "$SOURCE" --strategy variance --rounds 5 --seed 0 \
  --json runs/demo_trial.json
