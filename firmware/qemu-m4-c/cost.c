/* Cost of one sd_step on the emulated Cortex-M4F, in INSTRUCTIONS EXECUTED BY QEMU (run
 * with -icount shift=0: the virtual clock advances 1 ns per instruction), not cycles on
 * silicon. The SysTick timer (processor clock) is read around each sd_step; a loop of a
 * known instruction count calibrates instructions per tick (40 on mps2-an386: 25 MHz),
 * and an empty timed region gives the reading overhead, which is subtracted.
 * Three phases on the scenario's plant: open loop (patent law), open loop with the
 * load-angle observer (estimated angle), servo; then the same with patent-motor-real's
 * current parts (scenario_with_current_parts). Prints the mean and the largest count per
 * mode. */
#include <stdint.h>
#include <stdio.h>

#include "scenario.h"
#include "stepdamp.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define MASK24 0xFFFFFFu

/* Ticks elapsed from reading a to reading b of the 24-bit down-counter. */
static uint32_t elapsed(uint32_t a, uint32_t b) { return (a - b) & MASK24; }

/* 2 instructions per iteration (subs, bne) plus a few around it. */
static void spin(uint32_t n) {
    __asm volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n)::"cc");
}

static sd_config cfg;
static sd_state st;

static int measure(const char *name, int real, sd_mode mode, sd_compensation comp, double insn_per_tick,
                   double overhead_ticks) {
    sd_params p;
    sd_config_info ci;
    sd_state_info si;
    if (sd_params_patent_motor(mode, comp, &p) != SD_OK) {
        printf("FAIL: init %s\n", name);
        return 1;
    }
    scenario_with_current_parts(&p, real);
    if (sd_config_init(&p, &cfg) != SD_OK ||
        sd_state_init(&st) != SD_OK || sd_config_read(&cfg, &ci) != SD_OK || sd_state_read(&st, &si) != SD_OK) {
        printf("FAIL: init %s\n", name);
        return 1;
    }
    plant pl = plant_new(ci.period_s);
    int64_t theta = si.position_command;
    uint64_t total = 0;
    uint32_t most = 0;
    for (unsigned n = 0; n < SCENARIO_PERIODS; n++) {
        /* Estimated angle: standstill first (the R trim), as in the golden scenario. */
        float speed = (comp == SD_COMPENSATION_ESTIMATED && n < 500) ? 0.0f : 8.4f;
        sd_command_speed(&cfg, &st, speed);
        sd_measurement m = {pl.i_a, pl.i_b, encoder_count(theta)};
        sd_output out;
        uint32_t a = SYST_CVR;
        sd_status s = sd_step(&cfg, &st, &m, &out);
        uint32_t b = SYST_CVR;
        if (s != SD_OK || sd_state_read(&st, &si) != SD_OK || plant_advance(&pl, &cfg, &out, theta, si.speed_command_rad_s)) {
            printf("FAIL: step %s\n", name);
            return 1;
        }
        theta = si.position_command;
        uint32_t t = elapsed(a, b);
        total += t;
        if (t > most) most = t;
    }
    double mean = ((double)total / SCENARIO_PERIODS - overhead_ticks) * insn_per_tick;
    double max = ((double)most - overhead_ticks) * insn_per_tick;
    printf("sd_step %-45s mean %5.0f instructions, max %5.0f (+-%.0f per reading), %u periods\n", name, mean, max,
           insn_per_tick, SCENARIO_PERIODS);
    return 0;
}

int main(void) {
    SYST_RVR = MASK24;
    SYST_CVR = 0;
    SYST_CSR = 5u; /* enable, processor clock, no interrupt */
    /* Calibration: 4 million instructions. */
    uint32_t a = SYST_CVR;
    spin(2000000u);
    uint32_t b = SYST_CVR;
    double insn_per_tick = 4.0e6 / (double)elapsed(a, b);
    /* The reading overhead: two back-to-back reads, averaged. */
    uint32_t sum = 0;
    for (int i = 0; i < 1000; i++) {
        uint32_t x = SYST_CVR;
        uint32_t y = SYST_CVR;
        sum += elapsed(x, y);
    }
    double overhead = sum / 1000.0;
    printf("QEMU -icount shift=0: %.2f instructions per SysTick tick, reading overhead %.2f ticks\n", insn_per_tick,
           overhead);
    printf("(instructions executed by the emulator, not cycles on silicon)\n");
    int fail = 0;
    for (int real = 0; real <= 1; real++) {
        const char *names[3] = {"open loop, patent", "open loop, estimated angle", "servo, patent"};
        const char *names_real[3] = {"open loop, patent, current parts", "open loop, estimated angle, current parts",
                                     "servo, patent, current parts"};
        const char **n = real ? names_real : names;
        fail |= measure(n[0], real, SD_MODE_OPEN_LOOP, SD_COMPENSATION_PATENT, insn_per_tick, overhead);
        fail |= measure(n[1], real, SD_MODE_OPEN_LOOP, SD_COMPENSATION_ESTIMATED, insn_per_tick, overhead);
        fail |= measure(n[2], real, SD_MODE_SERVO, SD_COMPENSATION_PATENT, insn_per_tick, overhead);
    }
    return fail;
}
