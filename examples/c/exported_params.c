/* The identify -> firmware path without hand copying: motor_params.h is
 * written by `stepdamp export c-header --motor patent-motor --out examples/c/motor_params.h
 * --name motor --duration 0` (CI regenerates it and fails on a difference). This checks that the exported
 * initializer configures the controller and that the motor, drive and encoder it carries are
 * the library's own reference motor (the servo loop differs: the preset's is 40 Hz, the
 * core's reference 50 Hz). */
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
    printf("exported_params: %s\n", failures ? "FAILED" : "ok");
    return failures ? 1 : 0;
}
