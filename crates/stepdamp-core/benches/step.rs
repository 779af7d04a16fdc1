//! Cost of one drive step (open loop with the patent's law and with the estimated angle,
//! servo; three detent harmonics) on the host.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use stepdamp_core::*;

fn config(mode: Mode, compensation: Compensation) -> Config {
    Config::new(&Params::patent_motor(mode, compensation)).expect("valid preset")
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
