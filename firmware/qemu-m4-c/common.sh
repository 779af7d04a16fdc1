# Sourced by run-golden.sh and cost.sh, on top of firmware/qemu-lib.sh (QEMU, the Rust
# firmware build, run_qemu, the size check): the paths, the ARM C toolchain (installed with
# apt-get when missing: CI runs as root on a fresh machine) and its build.
tag=qemu-m4-c
# shellcheck source=../qemu-lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/../qemu-lib.sh"

here="$repo/firmware/qemu-m4-c"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$repo/target}"
out_dir="$CARGO_TARGET_DIR/qemu-m4-c"

# Debian's arm-none-eabi-gcc and newlib (rdimon.specs: printf/exit over semihosting).
have_toolchain() {
    command -v arm-none-eabi-gcc >/dev/null 2>&1 \
        && [[ -n "$(arm-none-eabi-gcc -print-file-name=rdimon.specs 2>/dev/null | grep /)" ]] \
        && [[ -f "$(arm-none-eabi-gcc -print-file-name=rdimon.specs)" ]]
}
if ! have_toolchain; then
    apt_install gcc-arm-none-eabi libnewlib-arm-none-eabi
    have_toolchain || { echo "$tag: arm-none-eabi-gcc with newlib still missing" >&2; exit 1; }
fi

need_qemu

# The C firmware ELFs (and the stepdamp-ffi staticlib) under $out_dir.
build_c_firmware() { make -s -C "$here" all; }
