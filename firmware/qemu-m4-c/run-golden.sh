#!/usr/bin/env bash
# Builds the C firmware (C scenario + the thumbv7em staticlib of stepdamp-ffi) and the
# Rust firmware (firmware/qemu-m4), runs both on QEMU mps2-an386, and fails unless the C
# firmware's output equals the Rust firmware's output of this run byte for byte (so a
# re-blessed firmware/qemu-m4/golden.txt needs nothing here). Also compares the C
# firmware's .text with size.txt (fails if it grew by more than 10 %).
#
#   bash firmware/qemu-m4-c/run-golden.sh           # check
#   bash firmware/qemu-m4-c/run-golden.sh --bless   # rewrite size.txt from this build
bless=0
case "${1:-}" in
    "") ;;
    --bless) bless=1 ;;
    *) echo "usage: $0 [--bless]" >&2; exit 2 ;;
esac
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

# The Rust firmware, built and run the way firmware/qemu-m4/run-golden.sh does.
rust_dir="$root/firmware/qemu-m4"
(cd "$rust_dir" && CARGO_TARGET_DIR="$rust_dir/target" cargo build --release --locked)
rust_elf="$rust_dir/target/thumbv7em-none-eabihf/release/qemu-m4"
c_elf="$out_dir/qemu-m4-c.elf"

echo "qemu-m4-c: $("$qemu" --version | head -n1); $(arm-none-eabi-gcc --version | head -n1)"
run_qemu "$rust_elf" "$out_dir/rust-output.txt"
run_qemu "$c_elf" "$out_dir/c-output.txt"

fail=0
if ! diff -u --label rust-firmware --label c-firmware "$out_dir/rust-output.txt" "$out_dir/c-output.txt"; then
    echo "qemu-m4-c: FAIL: the C firmware's output differs from the Rust firmware's" >&2
    fail=1
else
    echo "qemu-m4-c: ok, C firmware output equals the Rust firmware's ($(wc -l <"$out_dir/c-output.txt") lines, $(grep checksum "$out_dir/c-output.txt"))"
fi
if cmp -s "$out_dir/c-output.txt" "$rust_dir/golden.txt"; then
    echo "qemu-m4-c: (and equals firmware/qemu-m4/golden.txt)"
else
    echo "qemu-m4-c: note: differs from the committed firmware/qemu-m4/golden.txt (its own run-golden.sh reports that)"
fi

text_bytes="$(arm-none-eabi-size -A "$c_elf" | awk '$1 == ".text" { print $2 }')"
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
recorded="$(sed -n 's/^text_bytes=\([0-9][0-9]*\)$/\1/p' "$size_file" 2>/dev/null | head -n1)"
if [[ -z "$recorded" ]]; then
    echo "qemu-m4-c: FAIL: no text_bytes=N line in $size_file (measured $text_bytes; --bless records it)" >&2
    fail=1
elif (( text_bytes * 10 > recorded * 11 )); then
    echo "qemu-m4-c: FAIL: .text grew by more than 10 %: $text_bytes bytes, recorded $recorded (--bless if intended)" >&2
    fail=1
else
    echo "qemu-m4-c: ok, .text = $text_bytes bytes, recorded $recorded bytes in size.txt"
fi
exit "$fail"
