/* See scenario.h. Mirrors firmware/qemu-m4/src/main.rs statement for statement; any
 * change there must be made here too (the golden comparison fails otherwise). */
#include "scenario.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "real_motor_params.h"
#include "stepdamp.h"

/* Periods between printed lines. */
#define PRINT_EVERY 250u
/* Open-loop period whose current sample is NaN. */
#define NAN_AT 1500u

/* The plant's motor: the patent-motor's true values (as the Rust firmware's plant). */
#define KM 0.3f
#define NR 50
#define R 0.9f
#define L 2.5e-3f
#define VDC 48.0f
#define CPR 4000

plant plant_new(float ts) {
    plant p;
    p.i_a = 0.0f;
    p.i_b = 0.0f;
    p.decay = sd_ref_expf(-R * ts / L);
    p.gain = (1.0f - p.decay) / R;
    return p;
}

int plant_advance(plant *p, const sd_config *cfg, const sd_output *o, int64_t theta, float omega) {
    float ua, ub, s, c;
    if (sd_winding_voltages_per_vdc(cfg, o, &ua, &ub) != SD_OK) return 1;
    if (sd_ref_sincosf(sd_position_electrical_angle_rad(theta), &s, &c) != SD_OK) return 1;
    /* Torque Km(-i_a sin te + i_b cos te), so by power balance e = Km w (-sin te, cos te). */
    float e_a = -KM * omega * s;
    float e_b = KM * omega * c;
    p->i_a = p->decay * p->i_a + p->gain * (ua * VDC - e_a);
    p->i_b = p->decay * p->i_b + p->gain * (ub * VDC - e_b);
    return 0;
}

/* Exact for every int64 (Rust computes it in i128): theta = q*U + r with 0 <= r < U =
 * NR*2^32, so floor(theta*CPR/U) = q*CPR + floor(r*CPR/U). */
uint32_t encoder_count(int64_t theta) {
    const int64_t units_per_rev = (int64_t)NR << 32;
    int64_t q = theta / units_per_rev;
    int64_t r = theta % units_per_rev;
    if (r < 0) {
        r += units_per_rev;
        q -= 1;
    }
    return (uint32_t)((uint64_t)q * CPR + (uint64_t)(r * CPR / units_per_rev));
}

static uint32_t fnv_word(uint32_t h, uint32_t w) {
    for (int i = 0; i < 4; i++) {
        h = (h ^ ((w >> (8 * i)) & 0xffu)) * 0x01000193u;
    }
    return h;
}

static uint32_t bits(float x) {
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

void format_e4(char *buf, unsigned size, float x) {
    if (isnan(x)) { snprintf(buf, size, "NaN"); return; }
    if (isinf(x)) { snprintf(buf, size, x < 0 ? "-inf" : "inf"); return; }
    char tmp[32];
    snprintf(tmp, sizeof tmp, "%.4e", (double)x); /* e.g. "-5.9496e-03" */
    char *e = strchr(tmp, 'e');
    if (e == NULL) { snprintf(buf, size, "%s", tmp); return; }
    *e = '\0';
    /* The exponent as printf writes it: a sign and at least two digits. */
    const char *digit = e + 1;
    int negative = *digit == '-';
    if (*digit == '-' || *digit == '+') digit++;
    int exponent = 0;
    while (*digit >= '0' && *digit <= '9') exponent = 10 * exponent + (*digit++ - '0');
    snprintf(buf, size, "%se%s%d", tmp, negative ? "-" : "", exponent);
}

static int fail(const char *what, unsigned n) {
    printf("FAIL: %s at period %u\n", what, n);
    return 1;
}

typedef float (*speed_fn)(unsigned n);

static float speed_ol(unsigned n) { (void)n; return 8.4f; }
static float speed_oe(unsigned n) { return n < 500 ? 0.0f : 8.4f; }
static float speed_sv(unsigned n) { return n < 1000 ? 8.4f : (n < 2000 ? 0.0f : -8.4f); }

/* Statically placed, as a firmware would: the header's sizes make this possible. */
static sd_config cfg;
static sd_state st;

void scenario_with_current_parts(sd_params *p, int real) {
    if (!real) return;
    p->motor.ripple_per_amp_d = real_motor_RIPPLE_PER_AMP_D;
    p->motor.ripple_per_amp_d_count = sizeof real_motor_RIPPLE_PER_AMP_D / sizeof real_motor_RIPPLE_PER_AMP_D[0];
    p->motor.ripple_per_amp_q = real_motor_RIPPLE_PER_AMP_Q;
    p->motor.ripple_per_amp_q_count = sizeof real_motor_RIPPLE_PER_AMP_Q / sizeof real_motor_RIPPLE_PER_AMP_Q[0];
}

/* One phase of the patent-motor controller, with patent-motor-real's current parts if real
 * (lines start with prefix, then tag); adds its sample faults to *faults. */
static int run(const char *prefix, const char *tag, int real, sd_mode mode, sd_compensation comp, speed_fn speed,
               uint32_t *hash, uint32_t *faults) {
    sd_params p;
    sd_config_info ci;
    sd_state_info si;
    if (sd_params_patent_motor(mode, comp, &p) != SD_OK) return fail("sd_config_init", 0);
    scenario_with_current_parts(&p, real);
    if (sd_config_init(&p, &cfg) != SD_OK) return fail("sd_config_init", 0);
    if (sd_state_init(&st) != SD_OK || sd_config_read(&cfg, &ci) != SD_OK || sd_state_read(&st, &si) != SD_OK)
        return fail("sd_state_init", 0);
    plant pl = plant_new(ci.period_s);
    int64_t theta = si.position_command; /* the rotor: at the commanded position */
    for (unsigned n = 0; n < SCENARIO_PERIODS; n++) {
        if (sd_command_speed(&cfg, &st, speed(n)) != SD_OK) return fail("sd_command_speed", n);
        int nan = mode == SD_MODE_OPEN_LOOP && n == NAN_AT;
        sd_measurement m = {nan ? NAN : pl.i_a, pl.i_b, encoder_count(theta)};
        sd_output out;
        if (sd_step(&cfg, &st, &m, &out) != SD_OK) return fail("sd_step", n);
        if (sd_state_read(&st, &si) != SD_OK) return fail("sd_state_read", n);
        const float *d = out.duties;
        float iq = out.i_q_cmd_a;
        for (int k = 0; k < 3; k++) {
            if (!(d[k] >= 0.0f && d[k] <= 1.0f)) return fail("duty out of [0, 1] or non-finite i_q command", n);
        }
        if (!isfinite(iq)) return fail("duty out of [0, 1] or non-finite i_q command", n);
        *hash = fnv_word(*hash, bits(d[0]));
        *hash = fnv_word(*hash, bits(d[1]));
        *hash = fnv_word(*hash, bits(d[2]));
        *hash = fnv_word(*hash, bits(iq));
        if (n % PRINT_EVERY == 0 || (mode == SD_MODE_OPEN_LOOP && n >= NAN_AT && n < NAN_AT + 2)) {
            char a[24], b[24], c[24], q[24];
            format_e4(a, sizeof a, d[0]);
            format_e4(b, sizeof b, d[1]);
            format_e4(c, sizeof c, d[2]);
            format_e4(q, sizeof q, iq);
            printf("%s%s %4u d=[%s %s %s] iq=%11s faults=%u%s\n", prefix, tag, n, a, b, c, q, (unsigned)si.sample_faults,
                   nan ? " <- NaN i_a sample" : "");
        }
        if (plant_advance(&pl, &cfg, &out, theta, si.speed_command_rad_s) != 0) return fail("plant", n);
        theta = si.position_command;
    }
    char ia[24], ib[24], r[24], km[24], delta[24];
    format_e4(ia, sizeof ia, pl.i_a);
    format_e4(ib, sizeof ib, pl.i_b);
    format_e4(r, sizeof r, si.observer_r_hat_ohm);
    format_e4(km, sizeof km, si.observer_km_hat);
    format_e4(delta, sizeof delta, si.observer_delta_rad);
    printf("%s%s end i_a=%s i_b=%s faults=%u observer: R=%s Km=%s delta=%s\n", prefix, tag, ia, ib,
           (unsigned)si.sample_faults, r, km, delta);
    if (mode == SD_MODE_OPEN_LOOP && si.sample_faults != 1) return fail("expected exactly one sample fault", SCENARIO_PERIODS);
    *faults += si.sample_faults;
    return 0;
}

int scenario_run(void) {
    for (int real = 0; real <= 1; real++) {
        const char *prefix = real ? "real-" : "";
        uint32_t hash = 0x811c9dc5u, faults = 0;
        if (real)
            printf("with the current parts of patent-motor-real: the same laws, %u periods per phase\n",
                   SCENARIO_PERIODS);
        if (run(prefix, "ol", real, SD_MODE_OPEN_LOOP, SD_COMPENSATION_PATENT, speed_ol, &hash, &faults)) return 1;
        /* Open loop with the load-angle observer: standstill first (resistance trim), then run. */
        if (run(prefix, "oe", real, SD_MODE_OPEN_LOOP, SD_COMPENSATION_ESTIMATED, speed_oe, &hash, &faults)) return 1;
        /* Servo: forward, stop, reverse (the friction feed-forward follows the sign). */
        if (run(prefix, "sv", real, SD_MODE_SERVO, SD_COMPENSATION_PATENT, speed_sv, &hash, &faults)) return 1;
        printf("%schecksum fnv1a=0x%08x periods=%u faults=%u\n", prefix, (unsigned)hash, 3 * SCENARIO_PERIODS,
               (unsigned)faults);
    }
    return 0;
}
