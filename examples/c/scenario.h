/*
 * The golden scenario of firmware/qemu-m4, in C through the stepdamp C API: the
 * patent-motor controller against a tiny deterministic float plant, three phases of
 * 3000 periods (open loop with an injected NaN current sample; open loop with the
 * load-angle observer; servo forward/stop/reverse). Prints, after a title line chosen
 * by the caller, exactly the lines the Rust firmware prints, including the FNV-1a
 * checksum over the bits of every period's duties and i_q command.
 *
 * Shared by the host example (examples/c/demo.c) and the C firmware
 * (firmware/qemu-m4-c), so both run one scenario.
 */
#ifndef STEPDAMP_SCENARIO_H
#define STEPDAMP_SCENARIO_H

#include <stdint.h>

/* Periods per phase. */
#define SCENARIO_PERIODS 3000u

/* Runs the three phases, printing with printf; returns 0, or 1 after printing a
 * "FAIL: ..." line when an invariant broke (duty outside [0, 1], non-finite i_q command,
 * not exactly one sample fault in open loop, or an API call that did not return SD_OK). */
int scenario_run(void);

/* Formats x like Rust's `{:.4e}` (shortest exponent, no '+', e.g. "-5.9496e-3") into buf
 * (at least 24 bytes). */
void format_e4(char *buf, unsigned size, float x);

#endif
