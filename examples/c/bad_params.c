/* Bad parameter sets from C: each returns its documented, distinct status (see the
 * SD_ERR_* comments in stepdamp.h), and a refused call never crashes or uses the object.
 * Prints one line per check and "N passed, M failed"; exits non-zero on any failure. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "stepdamp.h"

static unsigned passed, failed;

static void expect(const char *what, sd_status got, sd_status want) {
    if (got == want) {
        passed++;
        printf("ok   %-48s -> %2d (%s)\n", what, (int)got, sd_status_str(got));
    } else {
        failed++;
        printf("FAIL %-48s -> %2d (%s), want %d (%s)\n", what, (int)got, sd_status_str(got), (int)want,
               sd_status_str(want));
    }
}

/* Zero-initialised like any C static: not a usable config until sd_config_init. */
static sd_config cfg;
static sd_state st;

static sd_params reference(void) {
    sd_params p;
    memset(&p, 0, sizeof p);
    sd_params_patent_motor(SD_MODE_SERVO, SD_COMPENSATION_PATENT, &p);
    return p;
}

int main(void) {
    sd_params p;
    sd_measurement m = {0.0f, 0.0f, 0};
    sd_output out;
    sd_harmonic table[SD_MAX_HARMONICS + 1];
    memset(table, 0, sizeof table);

    expect("reference parameters", sd_config_init((p = reference(), &p), &cfg), SD_OK);

    p = reference();
    p.motor.km_nm_per_a = 0.0f;
    expect("zero Km", sd_config_init(&p, &cfg), SD_ERR_KM);
    expect("step on the config whose init failed", sd_step(&cfg, &st, &m, &out), SD_ERR_NOT_INITIALIZED);

    p = reference();
    p.drive.bus_voltage_v = NAN;
    expect("NaN bus voltage", sd_config_init(&p, &cfg), SD_ERR_BUS_VOLTAGE);

    p = reference();
    p.motor.detent = table;
    p.motor.detent_count = 0;
    expect("0 harmonics with a non-NULL pointer", sd_config_init(&p, &cfg), SD_ERR_DETENT_POINTER_WITHOUT_COUNT);

    p = reference();
    p.motor.detent = NULL;
    p.motor.detent_count = 3;
    expect("3 harmonics with a NULL pointer", sd_config_init(&p, &cfg), SD_ERR_DETENT_NULL_WITH_COUNT);

    p = reference();
    for (unsigned k = 0; k < SD_MAX_HARMONICS + 1; k++) table[k].order = (uint16_t)(k + 1);
    p.motor.detent = table;
    p.motor.detent_count = SD_MAX_HARMONICS + 1;
    expect("harmonic count beyond SD_MAX_HARMONICS", sd_config_init(&p, &cfg), SD_ERR_DETENT_COUNT_BEYOND_CAPACITY);
    p.motor.detent_count = SD_MAX_HARMONICS; /* orders 1..=32, amplitude 0: valid */
    expect("SD_MAX_HARMONICS harmonics", sd_config_init(&p, &cfg), SD_OK);
    table[1].order = 1;
    expect("a harmonic order given twice", sd_config_init(&p, &cfg), SD_ERR_DUPLICATE_HARMONIC);

    /* A 5 N·m detent against 0.3 N·m/A × 1.9 A = 0.57 N·m of holding torque: refused. */
    p = reference();
    memset(table, 0, sizeof table);
    table[0].order = 4;
    table[0].amplitude_nm = 5.0f;
    p.motor.detent = table;
    p.motor.detent_count = 1;
    expect("detent beyond the holding torque", sd_config_init(&p, &cfg), SD_ERR_DETENT_AMPLITUDE);
    table[0].amplitude_nm = 0.5f;
    expect("detent within the holding torque", sd_config_init(&p, &cfg), SD_OK);

    p = reference();
    p.mode = 7;
    expect("mode not an SD_MODE_* value", sd_config_init(&p, &cfg), SD_ERR_INVALID_MODE);

    p = reference();
    p.drive.holding_current_a = 10.0f;
    expect("holding current above the limit", sd_config_init(&p, &cfg), SD_ERR_HOLDING_CURRENT);

    /* NULL pointers: a status each, never a crash. */
    p = reference();
    expect("NULL params", sd_config_init(NULL, &cfg), SD_ERR_NULL_POINTER);
    expect("NULL config", sd_config_init(&p, NULL), SD_ERR_NULL_POINTER);
    expect("NULL params out", sd_params_patent_motor(SD_MODE_SERVO, SD_COMPENSATION_OFF, NULL), SD_ERR_NULL_POINTER);
    expect("NULL state", sd_state_init(NULL), SD_ERR_NULL_POINTER);
    expect("valid config again", sd_config_init(&p, &cfg), SD_OK);
    expect("step before sd_state_init", sd_step(&cfg, &st, &m, &out), SD_ERR_NOT_INITIALIZED);
    expect("state init", sd_state_init(&st), SD_OK);
    expect("step with NULL config", sd_step(NULL, &st, &m, &out), SD_ERR_NULL_POINTER);
    expect("step with NULL state", sd_step(&cfg, NULL, &m, &out), SD_ERR_NULL_POINTER);
    expect("step with NULL measurement", sd_step(&cfg, &st, NULL, &out), SD_ERR_NULL_POINTER);
    expect("step with NULL output", sd_step(&cfg, &st, &m, NULL), SD_ERR_NULL_POINTER);
    expect("command speed with NULL state", sd_command_speed(&cfg, NULL, 1.0f), SD_ERR_NULL_POINTER);
    expect("state read with NULL out", sd_state_read(&st, NULL), SD_ERR_NULL_POINTER);
    expect("step with everything valid", sd_step(&cfg, &st, &m, &out), SD_OK);

    /* sd_motor_ripple: a current that is not a number or beyond drive.current_limit_a, a
     * table too small for the harmonics (the count says how many are needed). */
    uint32_t count = 0;
    expect("motor ripple at a NaN i_d", sd_motor_ripple(&p, NAN, 0.0f, table, SD_MAX_HARMONICS, &count),
           SD_ERR_OPERATING_CURRENT);
    expect("motor ripple beyond the current limit",
           sd_motor_ripple(&p, 0.0f, 1.01f * p.drive.current_limit_a, table, SD_MAX_HARMONICS, &count),
           SD_ERR_OPERATING_CURRENT);
    expect("motor ripple into a table of 1", sd_motor_ripple(&p, 1.0f, 0.0f, table, 1, &count),
           SD_ERR_CAPACITY_TOO_SMALL);
    if (count == 3) {
        passed++;
        printf("ok   %-48s -> %u\n", "its count: the detent's 3 orders", (unsigned)count);
    } else {
        failed++;
        printf("FAIL %-48s -> %u, want 3\n", "its count: the detent's 3 orders", (unsigned)count);
    }
    expect("motor ripple of a zero Km", sd_motor_ripple(&(sd_params){0}, 0.0f, 0.0f, NULL, 0, &count), SD_ERR_KM);

    /* The codes tested above are distinct, and so are their texts. */
    const sd_status codes[] = {SD_ERR_KM, SD_ERR_BUS_VOLTAGE, SD_ERR_DETENT_POINTER_WITHOUT_COUNT,
                               SD_ERR_DETENT_NULL_WITH_COUNT, SD_ERR_DETENT_COUNT_BEYOND_CAPACITY,
                               SD_ERR_NULL_POINTER, SD_ERR_NOT_INITIALIZED, SD_ERR_OPERATING_CURRENT,
                               SD_ERR_CAPACITY_TOO_SMALL, SD_OK};
    unsigned n = sizeof codes / sizeof codes[0], same = 0;
    for (unsigned i = 0; i < n; i++)
        for (unsigned j = 0; j < i; j++)
            same += codes[i] == codes[j] || strcmp(sd_status_str(codes[i]), sd_status_str(codes[j])) == 0;
    expect("distinct codes and texts (pairs equal)", (sd_status)same, 0);

    printf("%u passed, %u failed\n", passed, failed);
    return failed != 0;
}
