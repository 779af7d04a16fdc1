#!/usr/bin/env bash
# Builds the Cortex-M4F firmware, runs it in QEMU (mps2-an386) and diffs its semihosting
# output against golden.txt, and compares the firmware's .text size with the one recorded
# in size.txt (failing if it grew by more than 10 %). Writes no tracked file unless blessed.
#
#   bash firmware/qemu-m4/run-golden.sh           # check (exit 1 and show the diff on mismatch)
#   bash firmware/qemu-m4/run-golden.sh --bless   # rewrite golden.txt and size.txt from this run
#
# QEMU: `qemu-system-arm` on PATH, else .ci/cache/qemu/usr/bin/ (see .ci/install-qemu.sh),
# or the path in $QEMU_SYSTEM_ARM.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
bless=0
case "${1:-}" in
    "") ;;
    --bless) bless=1 ;;
    *) echo "usage: $0 [--bless]" >&2; exit 2 ;;
esac

qemu="${QEMU_SYSTEM_ARM:-}"
if [[ -z "$qemu" ]]; then
    if command -v qemu-system-arm >/dev/null 2>&1; then
        qemu="$(command -v qemu-system-arm)"
    elif [[ -x "$root/.ci/cache/qemu/usr/bin/qemu-system-arm" ]]; then
        qemu="$root/.ci/cache/qemu/usr/bin/qemu-system-arm"
    else
        echo "run-golden: qemu-system-arm not found; run: bash .ci/install-qemu.sh" >&2
        exit 1
    fi
fi

# Build inside the folder so that its .cargo/config.toml (target, linker script) applies;
# pin the target dir so the ELF path below holds whatever the caller's environment says.
export CARGO_TARGET_DIR="$here/target"
(cd "$here" && cargo build --release --locked)
elf="$CARGO_TARGET_DIR/thumbv7em-none-eabihf/release/qemu-m4"

out="$(mktemp)"
err="$(mktemp)"
trap 'rm -f "$out" "$err"' EXIT

echo "run-golden: $("$qemu" --version | head -n1)"
status=0
timeout 60 "$qemu" -cpu cortex-m4 -machine mps2-an386 -nographic \
    -semihosting-config enable=on,target=native -kernel "$elf" \
    </dev/null >"$out" 2>"$err" || status=$?
if [[ $status -ne 0 ]]; then
    [[ $status -eq 124 ]] && echo "run-golden: QEMU timed out after 60 s" >&2
    echo "run-golden: firmware/QEMU exited with status $status; output:" >&2
    cat "$out" "$err" >&2
    exit 1
fi
if [[ -s "$err" ]]; then
    echo "run-golden: QEMU stderr:" >&2
    cat "$err" >&2
fi

# .text size from the ELF section headers (python3 stdlib: no ARM binutils needed).
text_bytes="$(python3 - "$elf" <<'EOF'
import struct, sys

data = open(sys.argv[1], "rb").read()
assert data[:4] == b"\x7fELF" and data[4] == 1 and data[5] == 1, "not a 32-bit little-endian ELF"
shoff, = struct.unpack_from("<I", data, 0x20)
shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)

def section(i):
    # sh_name, sh_type, sh_flags, sh_addr, sh_offset, sh_size, ...
    return struct.unpack_from("<IIIIII", data, shoff + i * shentsize)

names_off = section(shstrndx)[4]

def name(i):
    start = names_off + section(i)[0]
    return data[start:data.index(b"\0", start)].decode()

print(sum(section(i)[5] for i in range(shnum) if name(i) == ".text"))
EOF
)"
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
recorded="$(sed -n 's/^text_bytes=\([0-9][0-9]*\)$/\1/p' "$size_file" 2>/dev/null | head -n1)"
if [[ -z "$recorded" ]]; then
    echo "run-golden: FAIL: no text_bytes=N line in $size_file (measured .text = $text_bytes bytes; --bless records it)" >&2
    fail=1
elif (( text_bytes * 10 > recorded * 11 )); then
    echo "run-golden: FAIL: .text grew by more than 10 %: measured $text_bytes bytes, recorded $recorded bytes in size.txt (bless with --bless if intended)" >&2
    fail=1
else
    echo "run-golden: ok, .text = $text_bytes bytes, recorded $recorded bytes in size.txt ($(( (text_bytes - recorded) * 100 / recorded )) %, limit +10 %)"
fi
exit "$fail"
