# Shared by check-symbols.sh and count-instructions.sh (sourced, not run).
#
# need_binutils: makes arm-none-eabi-objdump available, installing Debian's
#   binutils-arm-none-eabi when missing (as root, or through sudo).
# build_firmware: the release ELF (same build as run-golden.sh); sets $elf.
# disassemble FILE: demangled disassembly of $elf into FILE.
# STEP_ROOT: the #[inline(never)] wrapper around stepdamp_core::step in src/main.rs.

STEP_ROOT="qemu_m4::controller_step"

need_binutils() {
    command -v arm-none-eabi-objdump >/dev/null 2>&1 && return 0
    echo "installing binutils-arm-none-eabi (for arm-none-eabi-objdump)" >&2
    local sudo_=()
    [[ "$(id -u)" -eq 0 ]] || sudo_=(sudo)
    export DEBIAN_FRONTEND=noninteractive
    "${sudo_[@]}" apt-get install -y --no-install-recommends binutils-arm-none-eabi >&2 || {
        "${sudo_[@]}" apt-get update >&2
        "${sudo_[@]}" apt-get install -y --no-install-recommends binutils-arm-none-eabi >&2
    }
    command -v arm-none-eabi-objdump >/dev/null 2>&1
}

build_firmware() {
    export CARGO_TARGET_DIR="$here/target"
    (cd "$here" && cargo build --release --locked)
    elf="$CARGO_TARGET_DIR/thumbv7em-none-eabihf/release/qemu-m4"
}

disassemble() {
    arm-none-eabi-objdump -d -C --no-show-raw-insn "$elf" >"$1"
}
