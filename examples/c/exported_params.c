/* The identify -> firmware path without hand copying: motor_params.h is
 * written by `stepdamp export c-header --motor patent-motor --out examples/c/motor_params.h
 * --name motor --duration 0` (CI regenerates it and fails on a difference). This checks that the exported
 * initializer configures the controller and that the motor, drive and encoder it carries are
 * the library's own reference motor (the servo loop differs: the preset's is 40 Hz, the
 * core's reference 50 Hz), and reads the motor's ripple with sd_motor_ripple. */
#include <math.h>
#include <stdio.h>

#include "motor_params.h"

static int failures = 0;

static void expect(int ok, const char *what) {
    printf("%s %s\n", ok ? "ok  " : "FAIL", what);
    if (!ok) failures++;
}

int main(void) {
    static sd_config cfg;
    static sd_state st;
    sd_params ref;
    expect(sd_params_patent_motor(SD_MODE_OPEN_LOOP, SD_COMPENSATION_PATENT, &ref) == SD_OK, "reference motor");
    expect(sd_config_init(&motor_PARAMS, &cfg) == SD_OK, "exported parameters configure the controller");
    expect(sd_state_init(&st) == SD_OK, "state");
    expect(sd_command_speed(&cfg, &st, 4.2f) == SD_OK, "speed command");
    int steps_ok = 1;
    for (int k = 0; k < 1000; k++) {
        sd_measurement m = {0.0f, 0.0f, 0u};
        sd_output out;
        steps_ok &= sd_step(&cfg, &st, &m, &out) == SD_OK;
    }
    expect(steps_ok, "1000 steps");
    /* Field by field: the struct has padding after computation_delay_periods, and the
     * reference lives on the stack, so its padding bytes are indeterminate (a memcmp passed
     * or failed depending on the compiler and the stack). */
    const sd_drive *a = &motor_PARAMS.drive, *b = &ref.drive;
    expect(a->bus_voltage_v == b->bus_voltage_v && a->pwm_hz == b->pwm_hz
               && a->holding_current_a == b->holding_current_a && a->current_limit_a == b->current_limit_a
               && a->current_loop_bandwidth_hz == b->current_loop_bandwidth_hz && a->topology == b->topology
               && a->computation_delay_periods == b->computation_delay_periods,
           "drive equals the reference");
    expect(motor_PARAMS.encoder_counts_per_rev == ref.encoder_counts_per_rev, "encoder equals the reference");
    expect(motor_PARAMS.motor.km_nm_per_a == ref.motor.km_nm_per_a && motor_PARAMS.motor.pole_pairs == ref.motor.pole_pairs
               && motor_PARAMS.motor.resistance_ohm == ref.motor.resistance_ohm
               && motor_PARAMS.motor.inductance_h == ref.motor.inductance_h
               && motor_PARAMS.motor.detent_count == ref.motor.detent_count,
           "motor equals the reference");
    int detent_ok = 1;
    for (unsigned i = 0; i < motor_PARAMS.motor.detent_count && i < ref.motor.detent_count; i++) {
        detent_ok &= motor_PARAMS.motor.detent[i].order == ref.motor.detent[i].order
                     && motor_PARAMS.motor.detent[i].amplitude_nm == ref.motor.detent[i].amplitude_nm
                     && motor_PARAMS.motor.detent[i].phase_rad == ref.motor.detent[i].phase_rad;
    }
    expect(detent_ok, "detent harmonics equal the reference");

    /* The motor's ripple at open loop's operating point (holding current on d, none on q):
     * patent-motor has no [motor.flux], so it is its detent, orders 1, 2, 4; the 4th is
     * 0.02 N·m at phase 0 (torque on the rotor -A sin(4·θe + φ)). */
    sd_harmonic ripple[SD_MAX_HARMONIC_ORDER];
    uint32_t count = 0;
    sd_status s = sd_motor_ripple(&motor_PARAMS, motor_PARAMS.drive.holding_current_a, 0.0f, ripple,
                                  SD_MAX_HARMONIC_ORDER, &count);
    expect(s == SD_OK && count == 3 && ripple[0].order == 1 && ripple[1].order == 2 && ripple[2].order == 4,
           "motor ripple at the holding current: orders 1, 2, 4");
    if (s == SD_OK && count == 3) {
        printf("     order %u: %.6f N·m at %.6f rad\n", (unsigned)ripple[2].order, (double)ripple[2].amplitude_nm,
               (double)ripple[2].phase_rad);
        expect(fabsf(ripple[2].amplitude_nm - 0.02f) < 1e-7f && fabsf(ripple[2].phase_rad) < 1e-6f,
               "its 4th order is the detent's, 0.02 N·m at 0 rad");
    }
    printf("exported_params: %s\n", failures ? "FAILED" : "ok");
    return failures ? 1 : 0;
}
