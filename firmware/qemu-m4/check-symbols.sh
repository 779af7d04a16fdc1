#!/usr/bin/env bash
# Fails if the controller step on the Cortex-M4F can reach software double precision
# (__muldf3, __adddf3, __aeabi_d*), 64-bit division (__aeabi_uldivmod, __aeabi_ldivmod),
# fminf/fmaxf library calls or panic machinery.
#
# Walks the call graph of the release firmware (the one run-golden.sh runs) from the
# #[inline(never)] wrapper `controller_step` in src/main.rs, through every direct branch
# into another function (tools/callgraph.py over arm-none-eabi-objdump's disassembly);
# an indirect branch it cannot follow is a failure too. Installs Debian's
# binutils-arm-none-eabi when arm-none-eabi-objdump is missing (CI runs as root).
#
#   bash firmware/qemu-m4/check-symbols.sh
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=tools/common.sh
source "$here/tools/common.sh"

need_binutils
build_rust_firmware
dis="$(mktemp)"
trap 'rm -f "$dis"' EXIT
disassemble "$dis"
if python3 "$here/tools/callgraph.py" check "$dis" "$STEP_ROOT"; then
    echo "check-symbols: ok, nothing forbidden reachable from $STEP_ROOT"
else
    echo "check-symbols: FAIL: forbidden or unfollowable calls reachable from $STEP_ROOT (listed above)" >&2
    exit 1
fi
