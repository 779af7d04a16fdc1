# The set-up the firmware's QEMU scripts share (sourced, not run): the repository root,
# QEMU, the ARM tools, the Rust firmware build, a QEMU run, the .text size and its check
# against a recorded size, and the --bless argument.
#
#   tag=run-golden                                # prefix of this script's messages
#   source "$(dirname "${BASH_SOURCE[0]}")/../qemu-lib.sh"
#
# Defines:
#   $repo                 the repository root
#   sudo_ CMD...          CMD as root (directly, or through sudo)
#   apt_install PKG...    apt-get install --no-install-recommends (apt-get update first
#                         only when the install fails; CI runs as root on a fresh machine)
#   need_qemu             sets $qemu: $QEMU_SYSTEM_ARM, else qemu-system-arm on PATH, else
#                         .ci/cache/qemu/usr/bin/ (unpacked by .ci/install-qemu.sh)
#   need_binutils         makes arm-none-eabi-objdump and arm-none-eabi-size available
#   build_rust_firmware   release build of firmware/qemu-m4 (LTO, opt-level "s", its own
#                         target dir and .cargo/config.toml); sets $rust_elf
#   run_qemu ELF OUT [QEMU ARGS...]
#                         runs ELF on mps2-an386 (Cortex-M4F) with semihosting, output to
#                         OUT; fails, showing the output, on a non-zero exit or after
#                         $qemu_timeout_s (default 120) s
#   text_bytes ELF        prints the size of ELF's .text section in bytes
#   check_size FILE BYTES fails unless BYTES is at most 10 % above FILE's text_bytes=N
#   parse_bless [ARGS...] sets $bless to 1 for --bless, 0 for none (else usage, exit 2)
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
tag="${tag:-$(basename "$0" .sh)}"

sudo_() { if [[ "$(id -u)" -eq 0 ]]; then "$@"; else sudo "$@"; fi; }

apt_install() {
    echo "$tag: installing $* (apt-get)" >&2
    export DEBIAN_FRONTEND=noninteractive
    sudo_ apt-get install -y --no-install-recommends "$@" >&2 || {
        sudo_ apt-get update >&2
        sudo_ apt-get install -y --no-install-recommends "$@" >&2
    }
}

need_qemu() {
    qemu="${QEMU_SYSTEM_ARM:-}"
    [[ -n "$qemu" ]] && return 0
    if command -v qemu-system-arm >/dev/null 2>&1; then
        qemu="$(command -v qemu-system-arm)"
    elif [[ -x "$repo/.ci/cache/qemu/usr/bin/qemu-system-arm" ]]; then
        qemu="$repo/.ci/cache/qemu/usr/bin/qemu-system-arm"
    else
        echo "$tag: qemu-system-arm not found; run: bash .ci/install-qemu.sh" >&2
        exit 1
    fi
}

need_binutils() {
    command -v arm-none-eabi-objdump >/dev/null 2>&1 && return 0
    apt_install binutils-arm-none-eabi
    command -v arm-none-eabi-objdump >/dev/null 2>&1 || { echo "$tag: arm-none-eabi-objdump still missing" >&2; exit 1; }
}

build_rust_firmware() {
    # Built inside its folder so that its .cargo/config.toml (target, linker script)
    # applies; the target dir pinned so the ELF path holds whatever the caller's
    # environment says.
    local dir="$repo/firmware/qemu-m4"
    (cd "$dir" && CARGO_TARGET_DIR="$dir/target" cargo build --release --locked)
    rust_elf="$dir/target/thumbv7em-none-eabihf/release/qemu-m4"
}

run_qemu() {
    local elf="$1" dest="$2"
    shift 2
    local limit="${qemu_timeout_s:-120}" err status=0
    err="$(mktemp)"
    timeout "$limit" "$qemu" -cpu cortex-m4 -machine mps2-an386 -nographic "$@" \
        -semihosting-config enable=on,target=native -kernel "$elf" </dev/null >"$dest" 2>"$err" || status=$?
    if [[ $status -ne 0 ]]; then
        [[ $status -eq 124 ]] && echo "$tag: QEMU timed out after $limit s" >&2
        echo "$tag: $(basename "$elf") exited with status $status; output:" >&2
        cat "$dest" "$err" >&2
        rm -f "$err"
        return 1
    fi
    if [[ -s "$err" ]]; then
        echo "$tag: QEMU stderr:" >&2
        cat "$err" >&2
    fi
    rm -f "$err"
}

text_bytes() {
    # From the ELF section headers (python3 stdlib: no ARM binutils needed).
    python3 - "$1" <<'EOF'
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
}

check_size() {
    local file="$1" bytes="$2" recorded
    recorded="$(sed -n 's/^text_bytes=\([0-9][0-9]*\)$/\1/p' "$file" 2>/dev/null | head -n1)"
    if [[ -z "$recorded" ]]; then
        echo "$tag: FAIL: no text_bytes=N line in $file (measured .text = $bytes bytes; --bless records it)" >&2
        return 1
    elif ((bytes * 10 > recorded * 11)); then
        echo "$tag: FAIL: .text grew by more than 10 %: measured $bytes bytes, recorded $recorded bytes in $(basename "$file") (bless with --bless if intended)" >&2
        return 1
    fi
    echo "$tag: ok, .text = $bytes bytes, recorded $recorded bytes in $(basename "$file") ($(((bytes - recorded) * 100 / recorded)) %, limit +10 %)"
}

parse_bless() {
    bless=0
    case "${1:-}" in
        "") ;;
        --bless) bless=1 ;;
        *) echo "usage: $0 [--bless]" >&2; exit 2 ;;
    esac
}
