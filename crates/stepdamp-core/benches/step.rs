//! Cost of one drive step (open loop with the patent's law and with the estimated angle,
//! servo; three detent harmonics) on the host.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use stepdamp_core::*;

const DETENT: [Harmonic; 3] = [
    Harmonic { order: 4, amplitude_nm: 0.02, phase_rad: 0.0 },
    Harmonic { order: 2, amplitude_nm: 0.012, phase_rad: 0.7 },
    Harmonic { order: 1, amplitude_nm: 0.008, phase_rad: -1.1 },
];

fn config(mode: Mode, compensation: Compensation) -> Config {
    Config::new(&Params {
        motor: MotorModel {
            km_nm_per_a: 0.3,
            pole_pairs: 50,
            resistance_ohm: 0.9,
            inductance_h: 2.5e-3,
            coulomb_friction_nm: 0.01,
            detent: &DETENT,
        },
        drive: DriveSettings {
            bus_voltage_v: 48.0,
            pwm_hz: 20_000.0,
            holding_current_a: 1.9,
            current_limit_a: 3.0,
            current_loop_bandwidth_hz: 1500.0,
            topology: Topology::ThreeLeg,
            computation_delay_periods: 1,
        },
        encoder_counts_per_rev: 4000,
        servo: ServoGains::for_bandwidth(4.0e-5, 50.0, 300.0),
        mode,
        compensation,
    })
    .expect("valid preset")
}

fn bench(c: &mut Criterion) {
    for (name, mode, comp) in [
        ("open_loop_step", Mode::OpenLoop, Compensation::Patent),
        ("open_loop_step_estimated", Mode::OpenLoop, Compensation::Estimated),
        ("servo_step", Mode::Servo, Compensation::Patent),
    ] {
        let cfg = config(mode, comp);
        let mut st = State::default();
        st.command_speed(&cfg, 8.4);
        let mut k = 0u32;
        c.bench_function(name, |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let m = Measurement { i_a_a: 1.2 + (k & 7) as f32 * 0.01, i_b_a: -0.4, encoder_count: k >> 3 };
                black_box(step(black_box(&cfg), &mut st, black_box(&m)))
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
