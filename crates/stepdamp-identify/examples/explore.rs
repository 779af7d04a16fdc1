//! scratch
use stepdamp_core::Mode;
use stepdamp_sim::runlog::LogRow;
use stepdamp_sim::*;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let bw: f64 = args[1].parse().unwrap();
    let speed: f64 = args[2].parse().unwrap();
    let dur: f64 = args[3].parse().unwrap();
    let vf: f64 = args.get(4).map(|s| s.parse().unwrap()).unwrap_or(250.0);
    let mut m = Profile::preset("patent-motor").unwrap();
    m.servo.bandwidth_hz = bw;
    m.servo.velocity_filter_hz = vf;
    let opts = SimOptions { current_noise_a: 0.01, seed: 3, ..SimOptions::default() };
    let mut lp = ClosedLoop::new(&m, &m, Mode::Servo, Compensation::Off, &opts).unwrap();
    let spec = RunSpec { speed_rad_s: speed, ramp_s: 0.1, duration_s: dur, window_s: dur / 2.0 };
    let t0 = std::time::Instant::now();
    let mut rows = Vec::new();
    let mut stuck = 0usize;
    let mut rev = 0usize;
    let mut wmin = f64::INFINITY;
    let mut wmax = f64::NEG_INFINITY;
    let n0 = (0.5 * 20000.0) as usize;
    let met = run(&mut lp, &spec, 20000.0, |k, rec| {
        rows.push(LogRow::from_record(k, 20000.0, 50, rec));
        if k > n0 {
            let w = rec.plant.omega;
            wmin = wmin.min(w);
            wmax = wmax.max(w);
            if w.abs() < 1e-3 {
                stuck += 1
            }
            if w * speed < 0.0 {
                rev += 1
            }
        }
    });
    let el = t0.elapsed().as_secs_f64();
    println!(
        "sim {dur} s in {el:.3} s; vel err rms {:.4} pp {:.4}; omega [{wmin:.4},{wmax:.4}] stuck {stuck} rev {rev} of {}",
        met.vel_err_rms_rad_s,
        met.vel_err_pp_rad_s,
        rows.len() - n0
    );
    let iq: Vec<f64> = rows[n0..].iter().map(|r| r.i_q_a).collect();
    let mean = iq.iter().sum::<f64>() / iq.len() as f64;
    let mx = iq.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let mn = iq.iter().cloned().fold(f64::INFINITY, f64::min);
    println!("iq mean {mean:.4} min {mn:.4} max {mx:.4}");
    if let Some(p) = args.get(5) {
        let f = std::fs::File::create(p).unwrap();
        stepdamp_sim::runlog::write_csv(f, &rows).unwrap();
    }
}
