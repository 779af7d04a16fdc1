#!/usr/bin/env bash
# Instructions per sd_step on the emulated Cortex-M4F (QEMU mps2-an386 with -icount
# shift=0; see cost.c). Reports; passes unless the build or the run fails. These are
# instructions executed by the emulator, not cycles on silicon.
#
#   bash firmware/qemu-m4-c/cost.sh
# shellcheck source=common.sh
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
build_c_firmware
run_qemu "$out_dir/cost.elf" "$out_dir/cost.txt" -icount shift=0
cat "$out_dir/cost.txt"
