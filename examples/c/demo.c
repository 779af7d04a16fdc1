/* Host C example: the stepdamp controller from C against a tiny C plant (scenario.c),
 * printing the per-period trace and checksum of the Cortex-M4F golden scenario. */
#include <stdio.h>

#include "scenario.h"

int main(void) {
    printf("stepdamp C example (host): patent-motor, three legs, %u periods per phase\n", SCENARIO_PERIODS);
    return scenario_run();
}
