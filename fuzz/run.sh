#!/usr/bin/env bash
# Fuzzes the profile parser, the run-log reader, the static-table reader, the Prusa
# read-back reader, the correction-table reader (`sweep --table`), the study spec and the
# accelerometer capture reader (M973/M974 output) and Klipper's motion-analysis log reader with
# libFuzzer.
#
#   bash fuzz/run.sh [SECONDS_PER_TARGET] [TARGET…]      (default: 20 s each, all eight)
#
# Starts from the minimised seeds in fuzz/corpus/TARGET (kept in git) plus what earlier runs
# found in fuzz/corpus-run/TARGET (not kept). Prints each target's executions; a crash stops
# with the input saved under fuzz/artifacts/TARGET/ and a non-zero exit.
set -euo pipefail
cd "$(dirname "$0")"
secs=${1:-20}
shift || true
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(profile log static_table prusa_readback correction_table study_spec accel_capture klipper_log)
# cargo fuzz passes unstable (-Z) rustc flags; stable rustc accepts them with this.
export RUSTC_BOOTSTRAP=1
# No sanitizer: the code is safe Rust (unsafe_code is forbidden), so ASan would only slow
# it down; debug assertions catch arithmetic overflow.
flags=(-O --debug-assertions -s none)
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --version 0.13.2 --locked
cargo fuzz build "${flags[@]}"
for t in "${targets[@]}"; do
    dict=dict/csv.dict
    [[ $t == profile || $t == study_spec ]] && dict=dict/profile.dict
    [[ $t == prusa_readback || $t == correction_table ]] && dict=dict/prusa.dict
    [[ $t == accel_capture ]] && dict=dict/accel.dict
    [[ $t == klipper_log ]] && dict=dict/klipper.dict
    mkdir -p "corpus-run/$t"
    log=$(mktemp)
    if ! cargo fuzz run "${flags[@]}" "$t" "corpus-run/$t" "corpus/$t" -- \
        -max_total_time="$secs" -max_len=4096 -dict="$dict" -timeout=10 -rss_limit_mb=1024 \
        -print_final_stats=1 >"$log" 2>&1; then
        tail -40 "$log"
        echo "fuzz $t: FAILED (input saved under fuzz/artifacts/$t/)" >&2
        exit 1
    fi
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')
    echo "fuzz $t: $execs executions in ${secs} s, 0 crashes"
    rm -f "$log"
done
