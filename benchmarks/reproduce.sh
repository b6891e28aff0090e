#!/usr/bin/env bash
# The whole reproduction in one uninterrupted run: every registered experiment (or the ones
# named) at one scale into a fresh store, then the report, with the wall time of each.
#
#   benchmarks/reproduce.sh                      # all experiments, scale=full, store
#                                                # results/reproduce-<UTC time>/, reports/
#   benchmarks/reproduce.sh table5_3 fig4_4      # only these
#   SCALE=ci OUT=/tmp/rep benchmarks/reproduce.sh
#
# Environment: SCALE (full), STORE (a fresh folder under results/), OUT (report root:
# full scale in OUT/, ci in OUT/ci/; default reports), PSBENCH (psbench command; default the one of .venv or PATH), JOBS
# (worker processes; default psbench's). A failing experiment is reported and the run
# goes on; the exit status is the number of failed experiments (capped at 100).
set -uo pipefail
cd "$(dirname "$0")/.."
SCALE=${SCALE:-full}
STORE=${STORE:-results/reproduce-$(date -u +%Y%m%dT%H%M%S)}
BIN=$( [ -x .venv/bin/psbench ] && echo .venv/bin || dirname "$(command -v psbench)" )
PSBENCH=${PSBENCH:-$BIN/psbench}
if [ -n "${OUT:-}" ]; then out=(--out "$OUT"); else out=(); fi
if [ "$#" -gt 0 ]; then
  names=("$@")
else
  mapfile -t names < <("$BIN/python" -c \
    "from psbench import registry; print('\n'.join(registry.names('experiments')))")
fi
[ -e "$STORE" ] && { echo "reproduce: STORE=$STORE exists; give a fresh folder" >&2; exit 2; }
echo "reproduce: ${#names[@]} experiments at scale=$SCALE into $STORE ($(nproc) cores," \
     "load $(cut -d' ' -f1-3 /proc/loadavg))"
t0=$(date +%s); failed=0
for n in "${names[@]}"; do
  t=$(date +%s)
  if "$PSBENCH" +experiment="$n" scale="$SCALE" results_dir="$STORE" ${JOBS:+jobs=$JOBS} \
      > "$STORE.$n.log" 2>&1; then s=ok; else s=FAILED; failed=$((failed + 1)); fi
  printf 'reproduce: %-16s %-6s %6d s  (log %s)\n' "$n" "$s" $(( $(date +%s) - t )) "$STORE.$n.log"
done
echo "reproduce: experiments done in $(( $(date +%s) - t0 )) s wall"
t=$(date +%s)
"$BIN/psbench-report" --results "$STORE" --scale "$SCALE" "${out[@]}" --force --panels 2>&1 | tail -3
echo "reproduce: report written in $(( $(date +%s) - t )) s"
echo "reproduce: total $(( $(date +%s) - t0 )) s wall (load $(cut -d' ' -f1-3 /proc/loadavg))"
exit $(( failed > 100 ? 100 : failed ))
