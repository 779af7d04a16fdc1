# Shared by check-symbols.sh and count-instructions.sh (sourced, not run), on top of
# firmware/qemu-lib.sh (QEMU, need_binutils, build_rust_firmware, ...).
#
# disassemble FILE: demangled disassembly of $rust_elf into FILE.
# STEP_ROOT: the #[inline(never)] wrapper around stepdamp_core::step in src/main.rs.

# shellcheck source=../../qemu-lib.sh
source "$(dirname "${BASH_SOURCE[0]}")/../../qemu-lib.sh"

STEP_ROOT="qemu_m4::controller_step"

disassemble() {
    arm-none-eabi-objdump -d -C --no-show-raw-insn "$rust_elf" >"$1"
}
