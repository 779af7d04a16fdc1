#!/usr/bin/env bash
# docs/performance.md's table, regenerated: prints the markdown table of the
# table from measurements made now, on this machine.
#
#   bash scripts/perf-table.sh [earlier-commit] [pairs]     (defaults: 08f3470, 5 pairs)
#
# Rows: the criterion benchmarks of one controller step (crates/stepdamp-core/benches/step.rs),
# one plant RK4 step, one closed-loop period and one lock-step group of runs
# (crates/stepdamp-sim/benches/sim.rs), each the criterion point estimate (median-like
# middle of its confidence interval); then the README sweep's CPU and wall time, working
# tree against <earlier-commit>, from `scripts/bench-sweep.sh` (interleaved pairs, medians,
# ratio of the medians of CPU time). Everything it runs prints to stderr; the table alone
# goes to stdout, so `bash scripts/perf-table.sh > /tmp/table.md` keeps just the table.
# PERF_SWEEP_LOG=FILE takes the sweep rows from a saved bench-sweep.sh output instead of
# measuring again. It reports; it never fails on a time.
set -euo pipefail

old_rev=${1:-08f3470}
pairs=${2:-5}
root=$(git rev-parse --show-toplevel)
cd "$root"
tmp=$(mktemp -d /tmp/perf-table.XXXXXX)
trap 'rm -rf "$tmp"' EXIT

# Criterion's "name time: [lo mid hi]" lines → "name mid unit".
criterion() {
    cargo bench --quiet "$@" -- --warm-up-time 1 --measurement-time 3 2>/dev/null |
        awk '/^[a-z_\/0-9]+ *$/ { name = $1; next }
             /time:/ {
                 line = $0; sub(/^[^[]*\[/, "", line); split(line, v, " ")
                 n = ($1 ~ /time:/) ? name : $1
                 print n, v[3], v[4]
             }'
}
echo "== criterion: stepdamp-core step" >&2
criterion -p stepdamp-core --bench step >"$tmp/core.txt"
echo "== criterion: stepdamp-sim" >&2
criterion -p stepdamp-sim --bench sim 'plant_rk4_step|closed_loop_period|lockstep' >"$tmp/sim.txt"
cat "$tmp/core.txt" "$tmp/sim.txt" >&2

if [[ -n ${PERF_SWEEP_LOG:-} ]]; then
    # The output of an earlier `BENCH_CRITERION=0 bash scripts/bench-sweep.sh <rev> <pairs>`
    # of this tree (saves its two release builds and 2·pairs sweeps).
    echo "== README sweep: from $PERF_SWEEP_LOG" >&2
    cp "$PERF_SWEEP_LOG" "$tmp/sweep.txt"
    old_rev=$(awk '/^== medians/ { getline; getline; print $1; exit }' "$tmp/sweep.txt")
    pairs=$(awk '/^== medians over/ { print $4; exit }' "$tmp/sweep.txt")
else
    echo "== README sweep against $old_rev ($pairs interleaved pairs)" >&2
    BENCH_CRITERION=0 bash scripts/bench-sweep.sh "$old_rev" "$pairs" | tee "$tmp/sweep.txt" >&2
fi

get() { # file name → "value unit"
    awk -v n="$2" '$1 == n { print $2, $3; found = 1 } END { if (!found) print "n/a" }' "$1"
}
old_line=$(grep -A2 '^ *cpu_s' "$tmp/sweep.txt" | sed -n 2p)
new_line=$(grep -A2 '^ *cpu_s' "$tmp/sweep.txt" | sed -n 3p)
old_cpu=$(awk '{ print $(NF - 1) }' <<<"$old_line")
new_cpu=$(awk '{ print $(NF - 1) }' <<<"$new_line")
new_wall=$(awk '{ print $NF }' <<<"$new_line")
ratio=$(grep -o '[0-9.]*x$' "$tmp/sweep.txt" | tail -1)
sim_s=$(awk -v c="$new_cpu" 'BEGIN { printf "%.0f", 360 / c }')

cat <<EOF
Measured on this $(nproc)-core machine ($(date -u +%Y-%m-%d), load average $(cut -d' ' -f1 /proc/loadavg) at the end; \`bash scripts/perf-table.sh $old_rev $pairs\`):

| what | figure | reproduce |
|---|---|---|
| one open-loop controller step, 3 harmonics (host) | $(get "$tmp/core.txt" open_loop_step) | \`cargo bench -p stepdamp-core\` |
| one open-loop step with the estimated angle (observer) | $(get "$tmp/core.txt" open_loop_step_estimated) | \`cargo bench -p stepdamp-core\` |
| one servo controller step, 3 harmonics (host) | $(get "$tmp/core.txt" servo_step) | \`cargo bench -p stepdamp-core\` |
| plant RK4 step | $(get "$tmp/sim.txt" plant_rk4_step) | \`cargo bench -p stepdamp-sim\` |
| one closed-loop control period, open loop (RK4 + controller) | $(get "$tmp/sim.txt" closed_loop_period_open_loop) | \`cargo bench -p stepdamp-sim\` |
| one closed-loop control period, servo | $(get "$tmp/sim.txt" closed_loop_period_servo) | \`cargo bench -p stepdamp-sim\` |
| one lock-step group: 4 open-loop runs of 0.05 s (1,000 periods each) | $(get "$tmp/sim.txt" lockstep/open_loop_run_periods) | \`cargo bench -p stepdamp-sim -- lockstep\` |
| README sweep: 240 runs × 1.5 s, CPU time (user + sys, median) | ${new_cpu} s, about ${sim_s} simulated s per CPU s; ${new_wall} s wall | \`bash scripts/bench-sweep.sh $old_rev $pairs\` |
| README sweep against $old_rev, same run, interleaved | ${old_cpu} s → ${new_cpu} s CPU: ${ratio} less | \`bash scripts/bench-sweep.sh $old_rev $pairs\` |
EOF
