/*
 * The golden scenario of firmware/qemu-m4, in C through the stepdamp C API: the
 * patent-motor controller against a tiny deterministic float plant, three phases of
 * 3000 periods (open loop with an injected NaN current sample; open loop with the
 * load-angle observer; servo forward/stop/reverse), then the same three phases with the
 * current parts of patent-motor-real (the ripple per ampere of real_motor_params.h,
 * which `stepdamp export c-header --motor docs/profiles/patent-motor-real.toml --current
 * 1.9 --name real_motor --duration 0` writes; the plant keeps its sine back-EMF: these
 * phases measure the laws' cost). Prints, after a title line chosen by the caller,
 * exactly the lines the Rust firmware prints, including per motor the FNV-1a checksum
 * over the bits of every period's duties and i_q command.
 *
 * Shared by the host example (examples/c/demo.c) and the C firmware
 * (firmware/qemu-m4-c), so both run one scenario.
 */
#ifndef STEPDAMP_SCENARIO_H
#define STEPDAMP_SCENARIO_H

#include <stdint.h>

/* Periods per phase. */
#define SCENARIO_PERIODS 3000u

/* With real nonzero, gives *p (an sd_params_patent_motor) the current parts of
 * patent-motor-real: its ripple_per_amp_d/_q tables; with 0, leaves it as it is. */
struct sd_params;
void scenario_with_current_parts(struct sd_params *p, int real);

/* Runs the six phases, printing with printf; returns 0, or 1 after printing a
 * "FAIL: ..." line when an invariant broke (duty outside [0, 1], non-finite i_q command,
 * not exactly one sample fault in open loop, or an API call that did not return SD_OK). */
int scenario_run(void);

/* Two RL windings with back-EMF from a rigid rotor that follows the command exactly (the
 * patent-motor's true values). The exponential and sin/cos are the library's (sd_ref_*):
 * the Rust plant uses the same libm, so both plants compute the same bits. */
typedef struct {
    float i_a, i_b;
    float decay; /* exp(-R Ts / L) */
    float gain;  /* (1 - decay) / R: current a constant volt adds over one period */
} plant;

/* A plant at rest for control period ts (s). */
plant plant_new(float ts);

/* Applies the duties of o for one period with the rotor at theta (units of 2^-32
 * electrical rev) turning at omega rad/s; 0, or 1 if an API call failed. */
struct sd_config;
struct sd_output;
int plant_advance(plant *p, const struct sd_config *cfg, const struct sd_output *o, int64_t theta, float omega);

/* Raw encoder counter of a rotor at theta: floor to whole counts (4000 per revolution),
 * wrapping like a timer. */
uint32_t encoder_count(int64_t theta);

/* Formats x like Rust's `{:.4e}` (shortest exponent, no '+', e.g. "-5.9496e-3") into buf
 * (at least 24 bytes). */
void format_e4(char *buf, unsigned size, float x);

#endif
