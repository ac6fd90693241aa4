#!/usr/bin/env bash
# Set up (idempotent), train the default agent, evaluate it, print the results row.
set -euo pipefail
cd "$(dirname "$0")/.."
# base: torch and ncbot's base install are all that training and evaluating need (no robot, speech, browser)
bash scripts/setup.sh base
out="${1:-runs/default}"
# --overwrite: the main job is re-runnable; it replaces an earlier run in $out (ncbot train refuses by default)
ncbot train pipelines/configs/default.yaml --out "$out" --overwrite
ncbot eval "$out/checkpoint.pt" --games 3000 --first robot
ncbot eval "$out/checkpoint.pt" --games 3000 --first human
