#!/usr/bin/env bash
# Builds the Cortex-M4F firmware, runs it in QEMU (mps2-an386) and diffs its semihosting
# output against golden.txt, and compares the firmware's .text size with the one recorded
# in size.txt (failing if it grew by more than 10 %). Writes no tracked file unless blessed.
#
#   bash firmware/qemu-m4/run-golden.sh           # check (exit 1 and show the diff on mismatch)
#   bash firmware/qemu-m4/run-golden.sh --bless   # rewrite golden.txt and size.txt from this run
#
# QEMU, the build, the run and the size check: firmware/qemu-lib.sh (QEMU is
# $QEMU_SYSTEM_ARM, else `qemu-system-arm` on PATH, else .ci/cache/qemu/usr/bin/ from
# .ci/install-qemu.sh).
set -euo pipefail
tag=run-golden
# shellcheck source=../qemu-lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/../qemu-lib.sh"
here="$repo/firmware/qemu-m4"
parse_bless "$@"
need_qemu
build_rust_firmware

out="$(mktemp)"
trap 'rm -f "$out"' EXIT
echo "run-golden: $("$qemu" --version | head -n1)"
qemu_timeout_s=60 run_qemu "$rust_elf" "$out"
text_bytes="$(text_bytes "$rust_elf")"
size_file="$here/size.txt"
write_size() {
    {
        echo "text_bytes=$text_bytes"
        echo "# .text of firmware/qemu-m4 (thumbv7em-none-eabihf, release: lto, opt-level \"s\"):"
        echo "# stepdamp-core controller + test plant + cortex-m-rt + semihosting + core::fmt floats"
    } >"$size_file"
}

if [[ $bless -eq 1 ]]; then
    cat "$out" >"$here/golden.txt"
    write_size
    echo "run-golden: blessed golden.txt ($(wc -l <"$here/golden.txt") lines) and size.txt (.text = $text_bytes bytes)"
    exit 0
fi

fail=0
if ! diff -u --label golden.txt --label qemu-output "$here/golden.txt" "$out"; then
    echo "run-golden: FAIL: QEMU output differs from golden.txt (bless with --bless if intended)" >&2
    fail=1
else
    echo "run-golden: ok, output matches golden.txt ($(wc -l <"$out") lines)"
fi
# Size: at most 10 % above the recorded .text (smaller is fine; bless to record it).
check_size "$size_file" "$text_bytes" || fail=1
exit "$fail"
