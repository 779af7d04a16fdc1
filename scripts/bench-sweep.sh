#!/usr/bin/env bash
# CPU time of the README sweep, working tree against an earlier commit, measured side by
# side in one run:
#
#   bash scripts/bench-sweep.sh <earlier-commit> [pairs]      (pairs: default 5, at least 1)
#
# Builds the working tree and <earlier-commit> (checked out in a temporary `git worktree`
# under /tmp, removed afterwards) in release mode, then runs the README sweep
#   stepdamp sweep --motor patent-motor --mode both --compensation both --from 1 --to 40 --points 60
# with each binary in turn, alternating which goes first, and prints every run's user, sys
# and wall time (GNU /usr/bin/time), the medians and the ratio of the median CPU times
# (user + sys) of the earlier commit over the working tree. CPU time, not wall time: on a
# shared machine the wall clock measures the neighbours. It also compares the two sweep
# tables (largest relative difference of the velocity errors) and runs the criterion
# benchmark per control period of the working tree (crates/stepdamp-sim/benches/sim.rs).
#
# Environment: BENCH_OLD_TARGET_DIR (default target/bench-sweep-old) keeps the earlier
# commit's build between runs; BENCH_CRITERION=0 skips the criterion benchmark.
# It reports; it never fails on a time.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 <earlier-commit> [pairs]" >&2
    exit 2
fi
old_rev=$1
pairs=${2:-5}
if ! [[ $pairs =~ ^[1-9][0-9]*$ ]]; then
    echo "$0: pairs must be a whole number ≥ 1, got '$pairs'" >&2
    exit 2
fi
root=$(git rev-parse --show-toplevel)
cd "$root"
old_sha=$(git rev-parse --verify --quiet "$old_rev^{commit}") || {
    echo "$0: '$old_rev' is not a commit of this repository" >&2
    exit 2
}
[[ -x /usr/bin/time ]] || {
    echo "$0: needs GNU time at /usr/bin/time (apt-get install time)" >&2
    exit 2
}

tmp=$(mktemp -d /tmp/bench-sweep.XXXXXX)
cleanup() {
    git -C "$root" worktree remove --force "$tmp/old" 2>/dev/null || true
    git -C "$root" worktree prune 2>/dev/null || true
    rm -rf "$tmp"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

echo "== building the working tree ($(git rev-parse --short HEAD)$(git diff --quiet HEAD || echo ', modified'))"
cargo build --release --quiet -p stepdamp
cp target/release/stepdamp "$tmp/new"

echo "== building $old_rev ($(git rev-parse --short "$old_sha")) in a temporary worktree"
git worktree add --quiet --detach "$tmp/old" "$old_sha"
old_target=${BENCH_OLD_TARGET_DIR:-$root/target/bench-sweep-old}
(cd "$tmp/old" && CARGO_TARGET_DIR=$old_target cargo build --release --quiet -p stepdamp)
cp "$old_target/release/stepdamp" "$tmp/old-bin"

sweep_args=(sweep --motor patent-motor --mode both --compensation both --from 1 --to 40 --points 60)
# One run: prints "user sys wall" in s.
one() {
    local bin=$1 out=$2
    /usr/bin/time -f '%U %S %e' -o "$tmp/time" "$bin" --quiet "${sweep_args[@]}" --out "$out" >/dev/null
    cat "$tmp/time"
}

echo "== $pairs interleaved pairs of the README sweep (240 runs × 1.5 s simulated)"
printf '%-4s %-8s %8s %8s %8s %8s\n' pair build user_s sys_s cpu_s wall_s
: >"$tmp/old.txt"
: >"$tmp/new.txt"
for ((i = 1; i <= pairs; i++)); do
    if ((i % 2)); then order=(old new); else order=(new old); fi
    for which in "${order[@]}"; do
        if [[ $which == old ]]; then bin=$tmp/old-bin; else bin=$tmp/new; fi
        read -r u s w < <(one "$bin" "$tmp/out-$which")
        cpu=$(awk -v u="$u" -v s="$s" 'BEGIN { printf "%.2f", u + s }')
        echo "$cpu $w" >>"$tmp/$which.txt"
        printf '%-4s %-8s %8s %8s %8s %8s\n' "$i" "$which" "$u" "$s" "$cpu" "$w"
    done
done

median() { # column $2 of file $1
    sort -g -k"$2","$2" "$1" | awk -v c="$2" '{ v[NR] = $c } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}
old_cpu=$(median "$tmp/old.txt" 1)
new_cpu=$(median "$tmp/new.txt" 1)
old_wall=$(median "$tmp/old.txt" 2)
new_wall=$(median "$tmp/new.txt" 2)
echo "== medians over $pairs runs each (load average now: $(cut -d' ' -f1-3 /proc/loadavg), $(nproc) CPUs)"
printf '%-24s %10s %10s\n' "" "cpu_s" "wall_s"
printf '%-24s %10s %10s\n' "$old_rev ($(git rev-parse --short "$old_sha"))" "$old_cpu" "$old_wall"
printf '%-24s %10s %10s\n' "working tree" "$new_cpu" "$new_wall"
awk -v o="$old_cpu" -v n="$new_cpu" 'BEGIN { printf "CPU time ratio (earlier / working tree, medians): %.2fx\n", o / n }'

echo "== sweep tables: largest relative difference, working tree against $old_rev"
# Columns: mode, compensation, speed_cmd_rad_s, vel_err_rms_rad_s, vel_err_pp_rad_s, lost_sync.
awk -F, '
    FNR == 1 { for (i = 1; i <= NF; i++) col[FILENAME, $i] = i; next }
    {
        key = $(col[FILENAME, "mode"]) "," $(col[FILENAME, "compensation"]) "," $(col[FILENAME, "speed_cmd_rad_s"])
        rms = $(col[FILENAME, "vel_err_rms_rad_s"]); pp = $(col[FILENAME, "vel_err_pp_rad_s"])
        lost = $(col[FILENAME, "lost_sync"])
        if (FILENAME == ARGV[1]) { orms[key] = rms; opp[key] = pp; olost[key] = lost; next }
        if (!(key in opp)) { missing++; next }
        n++
        r = (rms - orms[key]) / orms[key]; if (r < 0) r = -r
        p = (pp - opp[key]) / opp[key]; if (p < 0) p = -p
        if (r > worst_rms) { worst_rms = r; at_rms = key }
        if (p > worst_pp) { worst_pp = p; at_pp = key }
        if (lost != olost[key]) flips++
    }
    END {
        printf "%d rows compared%s\n", n, missing ? sprintf(", %d rows without a match", missing) : ""
        printf "rms: largest relative difference %.3g %% (%s)\n", 100 * worst_rms, at_rms
        printf "pp:  largest relative difference %.3g %% (%s)\n", 100 * worst_pp, at_pp
        printf "lost_sync differs in %d rows\n", flips
    }' "$tmp/out-old/sweep.csv" "$tmp/out-new/sweep.csv"

if [[ ${BENCH_CRITERION:-1} != 0 ]]; then
    echo "== criterion, working tree: one RK4 step, one control period, run-periods in lock-step"
    cargo bench --quiet -p stepdamp-sim --bench sim -- --warm-up-time 1 --measurement-time 3 \
        'plant_rk4_step|closed_loop_period|lockstep' 2>/dev/null |
        grep -E '^[a-z_/0-9]+ *$|time:|thrpt:' || true
fi
