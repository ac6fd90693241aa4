#!/usr/bin/env bash
# CI: build ncbot's wheel, install it with the BASE dependencies only into a clean venv and run the main job's
# commands (shortened) from an empty folder; then add the [ray] extra and run a grid on a local Ray instance from
# that folder (its nodes must find the installed ncbot, not a checkout). Catches what the editable install of the tests cannot: a module or a
# data file (configs, weights, URDF, dialogues) missing from the wheel, a base command that imports an optional
# extra, a dependency the base install lacks.
#
#   bash scripts/check_wheel.sh [WORK_DIR]     (default: a temporary folder, removed afterwards)
#
# The venv gets torch==2.13.0 first (the CPU build from local disk: a plain torch requirement would pull the CUDA
# build), then PyPI's `envs` package, then the wheel with -c constraints.txt. `envs` is there on purpose: ncbot's
# packages keep the repository's folder names (envs, modules, pipelines, ...), which other PyPI packages also use;
# installed, they live under `ncbot.` (pyproject's package-dir), so both must import side by side.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
log() { printf '[check_wheel] %s\n' "$*"; }
fail() { printf '[check_wheel] FAIL: %s\n' "$*" >&2; exit 1; }

if [ -n "${1:-}" ]; then work=$(mkdir -p "$1" && cd "$1" && pwd); else work=$(mktemp -d); trap 'rm -rf "$work"' EXIT; fi
started=$(date +%s)
stamp() { printf '%ss' $(( $(date +%s) - started )); }

# 1. the wheel, built from a copy of the tracked (and new, not ignored) files: no build/ or egg-info leftovers
log "building the wheel"
mkdir -p "$work/src" "$work/dist"
git ls-files -z --cached --others --exclude-standard | tar --null -T - -cf - | tar -xf - -C "$work/src"
python -m pip wheel -q --no-deps -w "$work/dist" "$work/src"
wheel=$(ls "$work"/dist/ncbot-*.whl)
log "built $(basename "$wheel") ($(du -h "$wheel" | cut -f1)) at $(stamp)"

# 2. the package data the commands read must be in the wheel (every tracked one, except the vision reports: docs)
python - "$wheel" "$repo" <<'EOF'
import subprocess, sys, zipfile
wheel, repo = sys.argv[1:]
names = set(zipfile.ZipFile(wheel).namelist())
packages = ("ncbot", "fileio", "envs", "modules", "vision", "speech", "logs", "robot_sim", "pipelines")
tracked = subprocess.run(["git", "-C", repo, "ls-files", *packages], capture_output=True, text=True, check=True).stdout.split()
wanted = [p for p in tracked if not p.startswith("vision/reports/") and "/__pycache__/" not in p]
missing = [p for p in wanted if (p if p.startswith("ncbot/") else f"ncbot/{p}") not in names]
configs = sorted(p for p in names if p.startswith("ncbot/pipelines/configs/"))
strays = sorted({p.split("/")[0] for p in names if not p.startswith(("ncbot/", "ncbot-"))})
if strays:
    sys.exit("[check_wheel] FAIL: top-level names outside ncbot/ in the wheel: " + ", ".join(strays))
print(f"[check_wheel] wheel holds {len(configs)} configs under ncbot/pipelines/configs/ "
      f"(default.yaml: {'ncbot/pipelines/configs/default.yaml' in names}); "
      f"{len(wanted) - len(missing)}/{len(wanted)} tracked package files")
if missing:
    sys.exit("[check_wheel] FAIL: missing from the wheel: " + ", ".join(missing))
EOF

# 3. a clean venv: torch first, the foreign `envs`, then the wheel's base install at the tested versions
log "creating the venv"
python -m venv "$work/venv"
py="$work/venv/bin/python"
"$py" -m pip install -q torch==2.13.0
log "torch installed at $(stamp)"
"$py" -m pip install -q envs
"$py" -m pip install -q -c constraints.txt "$wheel"
log "base install done at $(stamp): venv $(du -sh "$work/venv" | cut -f1)"
"$py" -m pip check >/dev/null || fail "pip check: $("$py" -m pip check)"

# 4. the base install holds no optional extra
for dist in sapien pocketsphinx fastapi uvicorn websockets httpx rerun-sdk selenium ray open_spiel opencv-python; do
  if "$py" -m pip show -q "$dist" >/dev/null 2>&1; then fail "the base install pulled in $dist (an extra's package)"; fi
done
log "no extra installed (sapien, pocketsphinx, fastapi, uvicorn, websockets, httpx, rerun-sdk, selenium, ray, open_spiel, opencv-python)"

# 5. the main job's commands, shortened, from an empty folder (nothing of the clone on the path)
ncbot="$work/venv/bin/ncbot"
rm -rf "$work/empty" && mkdir -p "$work/empty" && cd "$work/empty"
where=$(env -u PYTHONPATH "$py" -c "import ncbot.pipelines; print(ncbot.pipelines.__file__)")
case "$where" in "$work/venv/"*) ;; *) fail "ncbot.pipelines comes from $where, not from the installed wheel" ;; esac
env -u PYTHONPATH "$ncbot" version
env -u PYTHONPATH "$ncbot" configs >configs.txt && head -3 configs.txt
# a shipped config by name, and the README's path (no pipelines/ folder here: the config shipped in the wheel)
env -u PYTHONPATH "$ncbot" train pipelines/configs/default.yaml --out readme-path collector.total_frames=1024 \
  collector.init_random_frames=512 eval.games=10 eval.periodic_games=10 train.eval_every_frames=1024 >readme.log 2>&1 \
  || { tail -20 readme.log; fail "ncbot train pipelines/configs/default.yaml"; }
env -u PYTHONPATH "$ncbot" train default train.device=cpu --out run collector.total_frames=4096 collector.init_random_frames=512 \
  eval.games=50 eval.periodic_games=50 train.eval_every_frames=2048 checkpoint.every_frames=2048 >train.log 2>&1 \
  || { tail -20 train.log; fail "ncbot train"; }
tail -1 train.log
env -u PYTHONPATH "$ncbot" eval run/checkpoint.pt --games 50 --first robot | tail -1
env -u PYTHONPATH "$ncbot" logs inspect run | tail -1
# a command of a missing extra: one line naming the pip command, exit 2
set +e; line=$(env -u PYTHONPATH "$ncbot" robot render -o mouth.png 2>&1); code=$?; set -e
[ "$code" = 2 ] && [ "$(printf '%s\n' "$line" | wc -l)" = 1 ] && [[ "$line" == *"pip install 'ncbot[robot]'"* ]] \
  || fail "ncbot robot render without [robot]: expected one line and exit 2, got exit $code: $line"
log "ncbot robot render without [robot]: $line"
log "main-job commands ran from an empty folder at $(stamp)"

# 6. no clash with PyPI's `envs`: both import side by side, and the Gymnasium id is registered from the ncbot name
env -u PYTHONPATH "$py" -c "import os; os.environ['NCBOT_PROBE'] = '7'; from envs import env; assert env('NCBOT_PROBE', var_type='integer') == 7" \
  || fail "PyPI's envs package is shadowed by ncbot's wheel"
env -u PYTHONPATH "$py" -c "import gymnasium, ncbot.envs as envs; env = gymnasium.make(envs.GYM_ID); env.reset(seed=0); print(envs.GYM_ID, 'from', envs.__name__)" \
  | tail -1 || fail "the Gymnasium id from ncbot.envs"
log "import envs gives PyPI's envs; ncbot's is ncbot.envs"

# 7. the [ray] extra on top: a two-run grid on a local Ray instance from the empty folder, its status read back
ray_from=$(date +%s)
"$py" -m pip install -q -c "$repo/constraints.txt" "$wheel[ray]"
log "[ray] installed in $(( $(date +%s) - ray_from ))s"
cd "$work/empty"
env -u PYTHONPATH "$ncbot" configs default >default.yaml
cat >grid.yaml <<'YAML'
runs_dir: runs
suites: {wheel: {standard: {config: default.yaml, overrides: [collector.total_frames=1024, collector.init_random_frames=512, eval.games=10, eval.periodic_games=10, train.eval_every_frames=1024, logger.mcap=false]}}}
grid: {suite: [wheel], game: [standard], agent: [proposed], temporal: [false]}
YAML
env -u PYTHONPATH "$ncbot" ablate grid.yaml --seeds 2 --workers 2 --backend ray --json >ray.json 2>ray.log \
  || { tail -20 ray.log; fail "ncbot ablate --backend ray from the wheel"; }
env -u PYTHONPATH "$py" - <<'EOF2' || fail "the Ray grid's summary: $(cat ray.json)"
import json
summary = json.load(open("ray.json"))
assert (summary["done"], summary["failed"], summary["unfinished"]) == (2, 0, []), summary
EOF2
env -u PYTHONPATH "$ncbot" ablate grid.yaml --seeds 2 --status --json | env -u PYTHONPATH "$py" -c \
  "import json, sys; status = json.load(sys.stdin); assert status['counts'] == {'finished': 2}, status; print('[check_wheel] status:', status['counts'], 'driver', status['driver']['backend'])" \
  || fail "ncbot ablate --status after the Ray grid"
log "a Ray grid from the wheel in an empty folder: 2 runs finished; the [ray] step took $(( $(date +%s) - ray_from ))s"
log "done in $(stamp)"
