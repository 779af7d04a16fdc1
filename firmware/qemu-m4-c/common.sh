# Sourced by run-golden.sh and cost.sh: paths, the ARM toolchain (installed with apt-get
# when missing: CI runs as root on a fresh machine), QEMU, and the build.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
out_dir="$CARGO_TARGET_DIR/qemu-m4-c"

sudo_() { if [[ "$(id -u)" -eq 0 ]]; then "$@"; else sudo "$@"; fi; }

# Debian's arm-none-eabi-gcc and newlib (rdimon.specs: printf/exit over semihosting).
have_toolchain() {
    command -v arm-none-eabi-gcc >/dev/null 2>&1 \
        && [[ -n "$(arm-none-eabi-gcc -print-file-name=rdimon.specs 2>/dev/null | grep /)" ]] \
        && [[ -f "$(arm-none-eabi-gcc -print-file-name=rdimon.specs)" ]]
}
if ! have_toolchain; then
    echo "qemu-m4-c: installing gcc-arm-none-eabi and libnewlib-arm-none-eabi (apt-get)" >&2
    export DEBIAN_FRONTEND=noninteractive
    if ! sudo_ apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi; then
        sudo_ apt-get update
        sudo_ apt-get install -y --no-install-recommends gcc-arm-none-eabi libnewlib-arm-none-eabi
    fi
    have_toolchain || { echo "qemu-m4-c: arm-none-eabi-gcc with newlib still missing" >&2; exit 1; }
fi

# QEMU as firmware/qemu-m4/run-golden.sh finds it.
qemu="${QEMU_SYSTEM_ARM:-}"
if [[ -z "$qemu" ]]; then
    if command -v qemu-system-arm >/dev/null 2>&1; then
        qemu="$(command -v qemu-system-arm)"
    elif [[ -x "$root/.ci/cache/qemu/usr/bin/qemu-system-arm" ]]; then
        qemu="$root/.ci/cache/qemu/usr/bin/qemu-system-arm"
    else
        echo "qemu-m4-c: qemu-system-arm not found; run: bash .ci/install-qemu.sh" >&2
        exit 1
    fi
fi

# run_qemu ELF OUT [extra QEMU args...]: semihosting output to OUT; fails on a non-zero exit.
run_qemu() {
    local elf="$1" dest="$2"
    shift 2
    local err status=0
    err="$(mktemp)"
    timeout 120 "$qemu" -cpu cortex-m4 -machine mps2-an386 -nographic "$@" \
        -semihosting-config enable=on,target=native -kernel "$elf" </dev/null >"$dest" 2>"$err" || status=$?
    if [[ $status -ne 0 ]]; then
        [[ $status -eq 124 ]] && echo "qemu-m4-c: QEMU timed out after 120 s" >&2
        echo "qemu-m4-c: $(basename "$elf") exited with status $status; output:" >&2
        cat "$dest" "$err" >&2
        rm -f "$err"
        return 1
    fi
    [[ -s "$err" ]] && { echo "qemu-m4-c: QEMU stderr:" >&2; cat "$err" >&2; }
    rm -f "$err"
}

make -s -C "$here" all
