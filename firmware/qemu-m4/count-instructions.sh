#!/usr/bin/env bash
# Counts the instructions the emulated Cortex-M4F executes per controller step, for the
# six phases of the golden firmware (open loop, open loop with the estimated angle, servo;
# on patent-motor, then with patent-motor-real's current parts: the `_real` modes; 3,000
# steps each), records the medians in instructions.txt next to size.txt and fails when one
# grew by more than 10 % over its record, or when any step of a phase executed more than
# the project's budget for its mode (budget.txt).
#
#   bash firmware/qemu-m4/count-instructions.sh           # check against instructions.txt
#   bash firmware/qemu-m4/count-instructions.sh --bless   # rewrite instructions.txt
#
# How: the release firmware (as run-golden.sh builds it) runs in QEMU with one instruction
# per translation block and the exec log (`-d exec,nochain`), filtered (`-dfilter`) to the
# functions reachable from the #[inline(never)] wrapper `controller_step` (the call graph
# of tools/callgraph.py) and the caller's return site; tools/count_steps.py counts the
# log lines from each entry of the wrapper to its return. The log is streamed, never
# written to disk. These are emulator instruction counts, not silicon cycles (the M4F
# needs ~1–1.5 cycles per instruction on average, more on flash wait states).
#
# QEMU and the build as in run-golden.sh (firmware/qemu-lib.sh: $QEMU_SYSTEM_ARM, PATH, or
# .ci/cache from .ci/install-qemu.sh); arm-none-eabi-objdump from Debian's
# binutils-arm-none-eabi (installed when missing).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=tools/common.sh
source "$here/tools/common.sh"
parse_bless "$@"
need_qemu
# One instruction per translation block: `-singlestep` until QEMU 8.0, then
# `-accel tcg,one-insn-per-tb=on` (the old flag is deprecated from 8.1).
if "$qemu" -help | grep -q -- '^-singlestep'; then
    one_insn=(-singlestep)
else
    one_insn=(-accel tcg,one-insn-per-tb=on)
fi

need_binutils
build_rust_firmware
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
disassemble "$work/dis.txt"
python3 "$here/tools/callgraph.py" reachable "$work/dis.txt" "$STEP_ROOT" >"$work/ranges.txt"
# Where the caller resumes: the address after each `bl <controller_step>` (4 bytes).
returns="$(python3 - "$work/dis.txt" "$STEP_ROOT" <<'PY'
import re
import sys

root = sys.argv[2]
call = re.compile(r"^\s*([0-9a-f]+):\s+bl\s+[0-9a-f]+ <" + re.escape(root) + r">$")
sites = [int(m.group(1), 16) + 4 for m in map(call.match, open(sys.argv[1])) if m]
print(",".join(f"{a:x}" for a in sites))
PY
)"
[[ -n "$returns" ]] || { echo "count-instructions: no direct call of $STEP_ROOT found" >&2; exit 1; }
filter="$(awk '{ printf "%s0x%s..0x%s", (NR > 1 ? "," : ""), $1, $2 }' "$work/ranges.txt")"
for r in ${returns//,/ }; do filter+=",0x$r..0x$r"; done

periods="$(sed -n 's/^const PERIODS: u32 = \([0-9_]*\);.*/\1/p' "$here/src/main.rs" | tr -d _)"
[[ -n "$periods" ]] || { echo "count-instructions: no 'const PERIODS: u32 = N;' in src/main.rs" >&2; exit 1; }

echo "count-instructions: $("$qemu" --version | head -n1), ${one_insn[*]}"
status=0
timeout 900 "$qemu" -cpu cortex-m4 -machine mps2-an386 -nographic \
    -semihosting-config enable=on,target=native -kernel "$rust_elf" \
    "${one_insn[@]}" -d exec,nochain -dfilter "$filter" </dev/null 2>&1 >"$work/stdout" \
    | python3 "$here/tools/count_steps.py" "$work/ranges.txt" "$STEP_ROOT" "$returns" >"$work/counts.txt" \
    || status=$?
if [[ $status -ne 0 ]]; then
    echo "count-instructions: QEMU or the counter failed (status $status); firmware output:" >&2
    cat "$work/stdout" >&2
    exit 1
fi
tail -n1 "$work/stdout" | grep -q 'checksum ' || { echo "count-instructions: the firmware did not finish:" >&2; cat "$work/stdout" >&2; exit 1; }

# Phases in the order of main() (its LAWS, per motor): open loop, estimated angle, servo,
# first on patent-motor, then with patent-motor-real's current parts; `periods` steps each.
modes=(open_loop estimated_angle servo)
names=("${modes[@]}" "${modes[@]/%/_real}")
summary="$(python3 - "$work/counts.txt" "$periods" "${names[@]}" <<'PY'
import statistics
import sys

counts = [int(x) for x in open(sys.argv[1])]
n, names = int(sys.argv[2]), sys.argv[3:]
if len(counts) != len(names) * n:
    sys.exit(f"count-instructions: {len(counts)} steps counted, expected {len(names)} x {n}")
for i, name in enumerate(names):
    c = counts[i * n:(i + 1) * n]
    print(name, int(statistics.median(c)), min(c), max(c))
PY
)"
budgets="$here/budget.txt"
record="$here/instructions.txt"
printf '%-21s %7s %7s %7s %9s %7s\n' mode median min max recorded budget
fail=0
while read -r name median min max; do
    rec="$({ sed -n "s/^$name=\([0-9][0-9]*\)$/\1/p" "$record" 2>/dev/null || true; } | head -n1)"
    budget="$(sed -n "s/^${name%_real}=\([0-9][0-9]*\)$/\1/p" "$budgets" | head -n1)"
    printf '%-21s %7d %7d %7d %9s %7s\n' "$name" "$median" "$min" "$max" "${rec:--}" "${budget:--}"
    # The budget holds at every step, blessing or not.
    if [[ -z "$budget" ]]; then
        echo "count-instructions: FAIL: no ${name%_real}=N line in $budgets" >&2
        fail=1
    elif (( max > budget )); then
        echo "count-instructions: FAIL: $name over budget: $max instructions at its largest step (median $median), budget $budget per step ($budgets)" >&2
        fail=1
    fi
    if [[ $bless -eq 0 ]]; then
        if [[ -z "$rec" ]]; then
            echo "count-instructions: FAIL: no $name=N line in $record (--bless records it)" >&2
            fail=1
        elif (( median * 10 > rec * 11 )); then
            echo "count-instructions: FAIL: $name grew by more than 10 %: $median instructions per step, recorded $rec (bless with --bless if intended)" >&2
            fail=1
        fi
    fi
done <<<"$summary"

if [[ $bless -eq 1 ]]; then
    {
        awk '{ print $1 "=" $2 }' <<<"$summary"
        echo "# Executed instructions per controller step on the emulated Cortex-M4F (QEMU mps2-an386,"
        echo "# firmware/qemu-m4 release build: LTO, opt-level \"s\"): median over $periods steps per mode,"
        echo "# counted by count-instructions.sh from the wrapper's entry to its return. Emulator"
        echo "# instruction counts, not silicon cycles. The period at 20 kHz is 8,400 cycles at 168 MHz."
        echo "# The _real modes: the same laws given patent-motor-real's current parts (src/main.rs)."
        awk '{ printf "# %s: min %d, max %d\n", $1, $3, $4 }' <<<"$summary"
    } >"$record"
    echo "count-instructions: blessed $record"
    exit "$fail"
fi
[[ $fail -eq 0 ]] && echo "count-instructions: ok, every mode within +10 % of $record and every step within budget.txt"
exit "$fail"
