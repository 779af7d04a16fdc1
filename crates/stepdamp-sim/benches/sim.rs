//! Simulator throughput: one plant RK4 step, one closed-loop control period, and the
//! README sweep (2 modes × 2 compensations × 60 speeds × 1.5 s).
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use stepdamp_core::Mode;
use stepdamp_sim::*;

fn bench(c: &mut Criterion) {
    let m = Profile::preset("patent-motor").unwrap();
    let p = PlantParams::from_profile(&m);
    let h = 2.5e-5;
    let band = p.stick_band(h);
    let mut x = PlantState { i_a: 1.9, ..Default::default() };
    c.bench_function("plant_rk4_step", |b| {
        b.iter(|| {
            x = p.rk4(black_box(&x), 3.0, -2.0, h, band);
            if !x.theta.is_finite() || x.theta.abs() > 1e3 {
                x = PlantState { i_a: 1.9, ..Default::default() };
            }
        })
    });
    let mut lp = ClosedLoop::new(&m, &m, Mode::OpenLoop, Compensation::Patent, &SimOptions::default()).unwrap();
    c.bench_function("closed_loop_period_open_loop", |b| b.iter(|| black_box(lp.period(8.4))));
    let mut lp = ClosedLoop::new(&m, &m, Mode::Servo, Compensation::Patent, &SimOptions::default()).unwrap();
    c.bench_function("closed_loop_period_servo", |b| b.iter(|| black_box(lp.period(8.4))));

    let spec = SweepSpec {
        speeds_rad_s: linear_grid(1.0, 40.0, 60),
        modes: vec![Mode::OpenLoop, Mode::Servo],
        compensations: vec![Compensation::Off, Compensation::Patent],
        run: RunSpec::at(1.0),
        options: SimOptions::default(),
    };
    let mut g = c.benchmark_group("sweep");
    g.sample_size(10);
    g.bench_function("readme_sweep_240_runs_360_sim_s", |b| {
        b.iter(|| black_box(sweep(&m, &m, &spec, &|| {}).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
