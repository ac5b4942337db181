#!/usr/bin/env bash
# Screen get-up variants in lock-step, one process per variant, side by side on one GPU.
#
#   MENAGERIE_ROOT=... bash benchmarks/getup_screen.sh OUTDIR "name:opts" ["name:opts" ...]
#
# Each variant ("hgt10:task.height_cost=1000", options as benchmarks/humanoid_getup.py reads
# them) runs MPPI on the G1 get-up (TASK, default g1_getup) over SEEDS (10) dev seeds from
# FIRST (200) with the world waiting for the planner (--loop lockstep): outcomes do not
# depend on the tick time, which the side-by-side processes share. One process compiles
# the kernels first so that the others find them in warp's cache. Writes
# OUTDIR/<task>_screen_<name>_<gpu>.json and a log per variant; prints the success counts.
set -euo pipefail
out=$1
shift
task=${TASK:-g1_getup}
gpu=$(nvidia-smi --query-gpu=name --format=csv,noheader | head -1)
tag=$(echo "${gpu##* }" | tr '[:upper:]' '[:lower:]')
mkdir -p "$out"
python3 - "$task" <<'PY'
import sys, time
import mpcbox
from mpcbox.registry import task_class
start = time.perf_counter()
problem = task_class(sys.argv[1])()
controller = mpcbox.make_controller("mppi", problem, backend="warp")
controller(problem.initial_state(), 0.0)
print(f"kernels ready in {time.perf_counter() - start:.1f} s")
PY
for variant in "$@"; do
  name=${variant%%:*}
  python3 benchmarks/humanoid_getup.py --task "$task" --backend warp --controllers mppi \
    --seeds "${SEEDS:-10}" --first-seed "${FIRST:-200}" --loop lockstep --variants "$variant" \
    --gpu "$gpu" --json "$out/${task}_screen_${name}_${tag}.json" > "$out/log_$name.txt" 2>&1 &
done
wait
grep -H '"successes"' "$out"/log_*.txt
