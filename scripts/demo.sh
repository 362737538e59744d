#!/usr/bin/env bash
# `make demo`: the simulated ROS 2 graph (mock arm, mock image, motion, explorer) as real
# processes over DDS on loopback, one full trial, the answer and where the trial record is.
# DEMO_ROUNDS (default 5) and DEMO_STRATEGY (default: the preset's, infogain) change the trial.
# `exec`: Ctrl-C or SIGTERM reaches the runner itself, which stops every node (none is left);
# an interrupted demo prints the command that resumes it.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p runs
exec .venv/bin/tactex graph run --sim --rounds "${DEMO_ROUNDS:-5}" \
  ${DEMO_STRATEGY:+--strategy "$DEMO_STRATEGY"} --seed 0 --record-dir runs/trials
