#!/usr/bin/env bash
# `make demo`: the simulated ROS 2 graph (mock arm, mock image, motion, explorer) as real
# processes over DDS on loopback, one full trial, the answer and where the trial record is.
# DEMO_ROUNDS (default 5) and DEMO_STRATEGY (default variance) change the trial.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p runs
exec .venv/bin/tactex graph run --sim --rounds "${DEMO_ROUNDS:-5}" \
  ${DEMO_STRATEGY:+--strategy "$DEMO_STRATEGY"} --seed 0 --record-dir runs/trials
