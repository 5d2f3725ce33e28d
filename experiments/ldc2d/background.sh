#!/usr/bin/env bash
# Start (or resume) the runs of one lid-driven-cavity figure in the background, one detached process
# per method, each logging to results/<profile>/ldc2d/logs/<method>_<fig>.log and recording its pid
# next to it. Re-running the same command resumes interrupted runs from their checkpoints and skips
# finished ones; a method whose process is still alive is not started twice.
#
#   experiments/ldc2d/background.sh [PROFILE] [FIG] [METHOD ...]     e.g.  paper fig7 sph tvf riemann
#   tail -f results/paper/ldc2d/logs/*_fig7.log                      follow the progress
#   make fig7                                                        once all runs are complete
set -euo pipefail
cd "$(dirname "$0")/../.."
PROFILE=${1:-paper}; FIG=${2:-fig7}; shift $(( $# > 2 ? 2 : $# )) || true
METHODS=("$@"); [ ${#METHODS[@]} -eq 0 ] && METHODS=(sph tvf riemann)
LOGS=results/$PROFILE/ldc2d/logs
mkdir -p "$LOGS"
export XLA_FLAGS="${XLA_FLAGS:---xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1}"
for m in "${METHODS[@]}"; do
  pidf="$LOGS/${m}_$FIG.pid"
  if [ -f "$pidf" ] && kill -0 "$(cat "$pidf")" 2>/dev/null; then
    echo "$m $FIG: already running (pid $(cat "$pidf"))"; continue
  fi
  setsid nohup nice -n 10 .venv/bin/python -m lab.experiment experiments/ldc2d --profile "$PROFILE" \
    --results "results/$PROFILE" --group "$FIG" --method "$m" --no-progress --log-every 10 \
    >> "$LOGS/${m}_$FIG.log" 2>&1 < /dev/null &
  echo $! > "$pidf"
  echo "$m $FIG: started (pid $!), log $LOGS/${m}_$FIG.log"
done
