/* The C firmware: firmware/qemu-m4's golden scenario through the stepdamp C API
 * (examples/c/scenario.c), printed over semihosting. run-golden.sh checks that its
 * output equals the Rust firmware's, bit for bit. */
#include <stdio.h>

#include "scenario.h"

int main(void) {
    printf("stepdamp-core on Cortex-M4F: patent-motor, three legs, %u periods per phase\n", SCENARIO_PERIODS);
    return scenario_run();
}
