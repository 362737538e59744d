#!/usr/bin/env bash
# The two done-when checks of the CNN learners on a GPU (docs/research/speed_stability.md, "On a GPU"),
# about five minutes on one GPU with 16 CPU cores; prints the figures and PASS / FAIL per check.
#
#   scripts/gpu_check.sh RECORDINGS_DIR [DEVICE]
#
# RECORDINGS_DIR (required): recorded presses replayed by the trials, an octopi-dev folder
# (material/N.mov; none ships with the repository); DEVICE: the torch device (default cuda).
# Needs torch's CUDA wheel (`make setup TORCH=cuda`, docs/install.md). Environment: ROUNDS
# (decisions after the baseline per trial, default 2: the thesis setting trains 10 epochs at
# 299 px per decision, so the CPU side of 10 seeded trials is the expensive part), SEEDS
# (default 10), JOBS (CPU trials run side by side, default 4, each with 16/JOBS threads), OUT
# (folder of the JSON outputs, default a new temporary folder), TACTEX (the command, default
# .venv/bin/tactex, else the tactex on PATH), PYTHON (the summary's interpreter, standard
# library only; default python3).
#
# 1. latency: `tactex bench latency --device DEVICE --touches 25` for the thesis setting with
#    small_inception and with inception_v3, and `cnn`, side by side with the CPU (the CPU's
#    thesis rows time 1 epoch, scaled to 10). Targets at 25 touches on the GPU: decision time
#    <= 1 s (small_inception), <= 5 s (inception_v3).
# 2. agreement: seeded `tactex trial --config seed_faithful` replays on DEVICE and on the CPU
#    over SEEDS seeds; target: the same prediction in >= 9 of 10.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 1 ] || { echo "usage: scripts/gpu_check.sh RECORDINGS_DIR [DEVICE]" >&2; exit 2; }
DATA=$1
DEV=${2:-cuda}
ROUNDS=${ROUNDS:-2}
SEEDS=${SEEDS:-10}
JOBS=${JOBS:-4}
OUT=${OUT:-$(mktemp -d -t tactex-gpu-check.XXXXXX)}
TACTEX=${TACTEX:-.venv/bin/tactex}
command -v "$TACTEX" >/dev/null || TACTEX=tactex
THREADS=$(( $(nproc) / JOBS > 0 ? $(nproc) / JOBS : 1 ))
[ -d "$DATA" ] || { echo "gpu_check: recordings folder $DATA not found" >&2; exit 2; }
mkdir -p "$OUT"
echo "gpu_check: device $DEV, recordings $DATA, $SEEDS seeds x $ROUNDS rounds, outputs in $OUT"

# 1. latency ------------------------------------------------------------------------------------
"$TACTEX" bench latency --device "$DEV" --touches 25 --repeats 2 --json "$OUT/latency.json" \
  --configs small_inception=seed_faithful \
            inception_v3=seed_faithful:learner.model=inception_v3 cnn

# 2. agreement ----------------------------------------------------------------------------------
trial() {   # seed device
  "$TACTEX" trial --source "replay:$DATA" --config seed_faithful --rounds "$ROUNDS" \
    --seed "$1" --device "$2" --set "learner.threads=$THREADS" \
    --json "$OUT/trial_${2//:/_}_$1.json" --quiet
}
start=$SECONDS
for s in $(seq 0 $((SEEDS - 1))); do trial "$s" "$DEV"; done
gpu_s=$((SECONDS - start))
start=$SECONDS
pids=()
for s in $(seq 0 $((SEEDS - 1))); do
  trial "$s" cpu &
  pids+=($!)
  if [ ${#pids[@]} -ge "$JOBS" ]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
done
for p in "${pids[@]}"; do wait "$p"; done
cpu_s=$((SECONDS - start))

OUT="$OUT" DEV="$DEV" SEEDS="$SEEDS" GPU_S="$gpu_s" CPU_S="$cpu_s" "${PYTHON:-python3}" - <<'EOF'
import json, os
from pathlib import Path
out, dev, n = Path(os.environ["OUT"]), os.environ["DEV"].replace(":", "_"), int(os.environ["SEEDS"])
lat = json.loads((out / "latency.json").read_text())
ok = True
for label, target in (("small_inception", 1.0), ("inception_v3", 5.0)):
    key = f"{label}@{os.environ['DEV']}"
    t = lat[key]["25"]
    cpu = lat[f"{label}@cpu"]["25"]
    good = t <= target
    ok &= good
    print(f"latency {label} at 25 touches: {t:.3f} s on {os.environ['DEV']} "
          f"(train {lat['train_s'][key]['25']:.3f} + score {lat['score_s'][key]['25']:.3f}), "
          f"{cpu:.2f} s on the CPU; target <= {target:g} s: {'PASS' if good else 'FAIL'}")
same, rows = 0, []
for s in range(n):
    g = json.loads((out / f"trial_{dev}_{s}.json").read_text())
    c = json.loads((out / f"trial_cpu_{s}.json").read_text())
    same += g["prediction"] == c["prediction"]
    rows.append(f"seed {s}: {dev} {g['prediction']} / cpu {c['prediction']} (truth {g['truth']})")
print("\n".join(rows))
need = -(-9 * n // 10)
good = same >= need
ok &= good
print(f"agreement: same prediction in {same} of {n} seeds (target >= {need}): "
      f"{'PASS' if good else 'FAIL'}; trials took {os.environ['GPU_S']} s on {dev}, "
      f"{os.environ['CPU_S']} s on the CPU")
raise SystemExit(0 if ok else 1)
EOF
