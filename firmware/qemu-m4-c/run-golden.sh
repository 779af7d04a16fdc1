#!/usr/bin/env bash
# Builds the C firmware (C scenario + the thumbv7em staticlib of stepdamp-ffi) and the
# Rust firmware (firmware/qemu-m4), runs both on QEMU mps2-an386, and fails unless the C
# firmware's output equals the Rust firmware's output of this run byte for byte (so a
# re-blessed firmware/qemu-m4/golden.txt needs nothing here). Also compares the C
# firmware's .text with size.txt (fails if it grew by more than 10 %).
#
#   bash firmware/qemu-m4-c/run-golden.sh           # check
#   bash firmware/qemu-m4-c/run-golden.sh --bless   # rewrite size.txt from this build
# shellcheck source=common.sh
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
parse_bless "$@"
build_c_firmware

# The Rust firmware, built and run the way firmware/qemu-m4/run-golden.sh does.
build_rust_firmware
rust_dir="$repo/firmware/qemu-m4"
c_elf="$out_dir/qemu-m4-c.elf"

echo "qemu-m4-c: $("$qemu" --version | head -n1); $(arm-none-eabi-gcc --version | head -n1)"
run_qemu "$rust_elf" "$out_dir/rust-output.txt"
run_qemu "$c_elf" "$out_dir/c-output.txt"

fail=0
if ! diff -u --label rust-firmware --label c-firmware "$out_dir/rust-output.txt" "$out_dir/c-output.txt"; then
    echo "qemu-m4-c: FAIL: the C firmware's output differs from the Rust firmware's" >&2
    fail=1
else
    echo "qemu-m4-c: ok, C firmware output equals the Rust firmware's ($(wc -l <"$out_dir/c-output.txt") lines, $(grep checksum "$out_dir/c-output.txt" | paste -sd " " -))"
fi
if cmp -s "$out_dir/c-output.txt" "$rust_dir/golden.txt"; then
    echo "qemu-m4-c: (and equals firmware/qemu-m4/golden.txt)"
else
    echo "qemu-m4-c: note: differs from the committed firmware/qemu-m4/golden.txt (its own run-golden.sh reports that)"
fi

text_bytes="$(text_bytes "$c_elf")"
size_file="$here/size.txt"
if [[ $bless -eq 1 ]]; then
    {
        echo "text_bytes=$text_bytes"
        echo "# .text of firmware/qemu-m4-c (arm-none-eabi-gcc -O2, newlib printf with floats,"
        echo "# stepdamp-ffi staticlib: cargo --release, lto, opt-level 3). Its golden output is"
        echo "# firmware/qemu-m4/golden.txt (the Rust firmware's, compared at every run)."
    } >"$size_file"
    echo "qemu-m4-c: blessed size.txt (.text = $text_bytes bytes)"
    exit "$fail"
fi
check_size "$size_file" "$text_bytes" || fail=1
exit "$fail"
