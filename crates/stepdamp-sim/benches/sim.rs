//! Simulator throughput: one plant RK4 step, one closed-loop control period, LANES control
//! periods in lock-step (the sweep's inner loop, reported per run-period), and the README
//! sweep (2 modes × 2 compensations × 60 speeds × 1.5 s). `scripts/bench-sweep.sh` runs
//! the per-period ones beside its CPU-time comparison of the whole sweep.
#![allow(missing_docs)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use stepdamp_core::Mode;
use stepdamp_sim::lanes::{Integrator, LANES, StateLanes};
use stepdamp_sim::*;

fn bench(c: &mut Criterion) {
    let m = Profile::preset("patent-motor").unwrap();
    let p = PlantParams::from_profile(&m);
    let h = 1.0 / m.drive.pwm_hz / f64::from(SimOptions::default().substeps);
    let band = p.stick_band(h);
    let mut it = Integrator::<1>::new(&p);
    let start = StateLanes::from_states(&[PlantState { i_a: 1.9, ..Default::default() }]);
    let mut x = start;
    c.bench_function("plant_rk4_step", |b| {
        b.iter(|| {
            it.rk4(&mut x, black_box(&[3.0]), black_box(&[-2.0]), &[0.0], h, band);
            if !x.theta[0].is_finite() || x.theta[0].abs() > 1e3 {
                x = start;
            }
        })
    });
    let mut lp = ClosedLoop::new(&m, &m, Mode::OpenLoop, Compensation::Patent, &SimOptions::default()).unwrap();
    c.bench_function("closed_loop_period_open_loop", |b| b.iter(|| black_box(lp.period(8.4))));
    let mut lp = ClosedLoop::new(&m, &m, Mode::Servo, Compensation::Patent, &SimOptions::default()).unwrap();
    c.bench_function("closed_loop_period_servo", |b| b.iter(|| black_box(lp.period(8.4))));

    // LANES 0.05 s runs (1000 periods each) in lock-step, as a sweep group runs them.
    let run = RunSpec { dwell_s: 0.0, ramp_s: 0.0, duration_s: 0.05, window_s: 0.05, ..RunSpec::at(8.4) };
    let (n, _) = run.periods(m.drive.pwm_hz, m.motor.pole_pairs);
    let specs: Vec<RunSpec> = (0..LANES).map(|i| RunSpec { speed_rad_s: 8.4 + i as f64, ..run }).collect();
    let fresh = || -> Vec<ClosedLoop> {
        (0..LANES)
            .map(|_| ClosedLoop::new(&m, &m, Mode::OpenLoop, Compensation::Patent, &SimOptions::default()).unwrap())
            .collect()
    };
    let mut g = c.benchmark_group("lockstep");
    g.throughput(Throughput::Elements((n * LANES) as u64));
    g.bench_function("open_loop_run_periods", |b| {
        b.iter_batched(
            fresh,
            |mut loops| black_box(run_lockstep::<LANES>(&mut loops, &specs, m.drive.pwm_hz).unwrap()),
            criterion::BatchSize::LargeInput,
        )
    });
    g.finish();

    let spec = SweepSpec {
        speeds_rad_s: linear_grid(1.0, 40.0, 60).unwrap(),
        modes: vec![Mode::OpenLoop, Mode::Servo],
        compensations: vec![Compensation::Off, Compensation::Patent],
        run: RunSpec::at(1.0),
        options: SimOptions::default(),
        table: None,
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
