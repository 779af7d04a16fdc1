//! Runs the `stepdamp-core` controller on a Cortex-M4F (QEMU `mps2-an386`) against a tiny
//! deterministic `f32` plant and prints a golden trace over semihosting.
//!
//! Plant: each winding is an exact first-order RL discretisation driven by the leg duties
//! (through [`Topology::winding_voltages_per_vdc`]) minus the back-EMF of a rigid rotor
//! that follows the command exactly; the encoder count is that rotor's angle quantised.
//!
//! Motors: the three laws (open loop with the patent's law at `θ_cmd`, open loop with the
//! estimated angle, servo) run first on `patent-motor` (detent only), then on the same
//! controller given the current parts of `patent-motor-real` ([`real_motor`]), whose servo
//! and estimated laws evaluate the ripple per ampere every step
//! (docs/design.md#real-motors-flux-harmonics). The plant keeps its sine back-EMF for both:
//! the second half measures what the laws cost, not how well they cancel a real ripple.
//!
//! Output: one line every [`PRINT_EVERY`] periods (leg duties and the i_q command to five
//! significant digits), the periods around an injected NaN current sample, and per motor a
//! checksum (FNV-1a over the bits of every period's duties and i_q command). `run-golden.sh`
//! diffs it against `golden.txt`. Exits QEMU with success, or failure on any broken invariant.
#![no_std]
#![no_main]

use core::panic::PanicInfo;

use cortex_m_rt::{ExceptionFrame, entry, exception};
use cortex_m_semihosting::{debug, hprintln};
use stepdamp_core::{
    Compensation, Config, CurrentRipple, LegDuties, Measurement, Mode, Output, Params, Position, State, Topology, step,
};

/// The ripple per ampere of `docs/profiles/patent-motor-real.toml`, `RIPPLE_PER_AMP_D` and
/// `RIPPLE_PER_AMP_Q` (N·m/A, the detent's convention): read by `build.rs` from
/// `examples/c/real_motor_params.h`, which `stepdamp export c-header` writes (the command is
/// in that file; the C firmware includes the same file).
mod real_motor {
    include!(concat!(env!("OUT_DIR"), "/real_motor.rs"));
}

/// Periods between printed lines.
const PRINT_EVERY: u32 = 250;
/// Periods per phase.
const PERIODS: u32 = 3000;
/// Open-loop period whose current sample is NaN.
const NAN_AT: u32 = 1500;

const KM: f32 = 0.3;
const NR: u16 = 50;
const R: f32 = 0.9;
const L: f32 = 2.5e-3;
const VDC: f32 = 48.0;
const CPR: u32 = 4000;

/// Two RL windings with back-EMF from a rotor that follows the command exactly.
struct Plant {
    i_a: f32,
    i_b: f32,
    /// `exp(−R Ts / L)`.
    decay: f32,
    /// `(1 − decay) / R`: the current a constant voltage adds over one period, per volt.
    gain: f32,
}

impl Plant {
    fn new(ts: f32) -> Self {
        let decay = libm::expf(-R * ts / L);
        Plant { i_a: 0.0, i_b: 0.0, decay, gain: (1.0 - decay) / R }
    }

    /// Applies `duties` for one period with the rotor at `theta` turning at `omega` rad/s.
    fn advance(&mut self, topology: Topology, duties: &LegDuties, theta: Position, omega: f32) {
        let (ua, ub) = topology.winding_voltages_per_vdc(duties);
        let (s, c) = libm::sincosf(theta.electrical_angle_rad());
        // Torque Km(−i_a sin θe + i_b cos θe), so by power balance e = Km ω (−sin θe, cos θe).
        let e_a = -KM * omega * s;
        let e_b = KM * omega * c;
        self.i_a = self.decay * self.i_a + self.gain * (ua * VDC - e_a);
        self.i_b = self.decay * self.i_b + self.gain * (ub * VDC - e_b);
    }
}

/// Raw encoder counter of a rotor at `theta` (floor to whole counts, wrapping like a timer).
fn encoder_count(theta: Position) -> u32 {
    let units_per_rev = i128::from(NR) << 32;
    (i128::from(theta.0) * i128::from(CPR)).div_euclid(units_per_rev) as u32
}

/// One controller step, kept out of line so that `check-symbols.sh` can walk its call
/// graph and `count-instructions.sh` can count the instructions from its entry to its
/// return. Every phase calls it [`PERIODS`] times in the order of `main`, which is how the
/// count tells the modes apart.
#[inline(never)]
fn controller_step(cfg: &Config, st: &mut State, m: &Measurement) -> Output {
    step(cfg, st, m)
}

/// FNV-1a over 32-bit words.
struct Fnv(u32);

impl Fnv {
    fn word(&mut self, w: u32) {
        for b in w.to_le_bytes() {
            self.0 = (self.0 ^ u32::from(b)).wrapping_mul(0x0100_0193);
        }
    }
}

fn fail(what: &str, n: u32) -> ! {
    hprintln!("FAIL: {} at period {}", what, n);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::bkpt();
    }
}

/// A law of the scenario: mode, compensation and the speed command in rad/s at period `n`.
type Law = (Mode, Compensation, fn(u32) -> f32);

/// The laws every motor runs, tagged, in the order `count-instructions.sh` splits the counts by.
const LAWS: [(&str, Law); 3] = [
    ("ol", (Mode::OpenLoop, Compensation::Patent, |_| 8.4)),
    // Open loop with the load-angle observer: standstill first (resistance trim), then run.
    ("oe", (Mode::OpenLoop, Compensation::Estimated, |n| if n < 500 { 0.0 } else { 8.4 })),
    // Servo: forward, stop, reverse (the friction feed-forward follows the sign).
    (
        "sv",
        (Mode::Servo, Compensation::Patent, |n| match n {
            0..1000 => 8.4,
            1000..2000 => 0.0,
            _ => -8.4,
        }),
    ),
];

/// Runs one phase of [`PERIODS`] periods of the `patent-motor` controller given `ripple`;
/// `speed(n)` gives the command in rad/s; lines start with the two parts of `tag`. Returns
/// the sample faults.
fn run(tag: (&str, &str), ripple: CurrentRipple<'static>, (mode, compensation, speed): Law, hash: &mut Fnv) -> u32 {
    let mut params = Params::patent_motor(mode, compensation);
    params.motor.current_ripple = ripple;
    let cfg = match Config::new(&params) {
        Ok(c) => c,
        Err(_) => fail("Config::new", 0),
    };
    let topology = cfg.topology();
    let mut st = State::default();
    let mut plant = Plant::new(cfg.period_s());
    // The rotor: at the commanded position of each period.
    let mut theta = st.position_command();
    for n in 0..PERIODS {
        st.command_speed(&cfg, speed(n));
        let nan = mode == Mode::OpenLoop && n == NAN_AT;
        let m = Measurement {
            i_a_a: if nan { f32::NAN } else { plant.i_a },
            i_b_a: plant.i_b,
            encoder_count: encoder_count(theta),
        };
        let out = controller_step(&cfg, &mut st, &m);
        let d = out.duties.0;
        let iq = out.signals.i_dq_cmd.q;
        if !d.iter().all(|x| (0.0..=1.0).contains(x)) || !iq.is_finite() {
            fail("duty out of [0, 1] or non-finite i_q command", n);
        }
        for x in [d[0], d[1], d[2], iq] {
            hash.word(x.to_bits());
        }
        if n % PRINT_EVERY == 0 || (mode == Mode::OpenLoop && (NAN_AT..NAN_AT + 2).contains(&n)) {
            hprintln!(
                "{}{} {:4} d=[{:.4e} {:.4e} {:.4e}] iq={:11.4e} faults={}{}",
                tag.0,
                tag.1,
                n,
                d[0],
                d[1],
                d[2],
                iq,
                st.sample_faults,
                if nan { " <- NaN i_a sample" } else { "" }
            );
        }
        plant.advance(topology, &out.duties, theta, st.speed_command_rad_s());
        theta = st.position_command();
    }
    hprintln!(
        "{}{} end i_a={:.4e} i_b={:.4e} faults={} observer: R={:.4e} Km={:.4e} delta={:.4e}",
        tag.0,
        tag.1,
        plant.i_a,
        plant.i_b,
        st.sample_faults,
        st.observer.r_hat_ohm,
        st.observer.km_hat,
        st.observer.delta_rad
    );
    if mode == Mode::OpenLoop && st.sample_faults != 1 {
        fail("expected exactly one sample fault", PERIODS);
    }
    st.sample_faults
}

#[entry]
fn main() -> ! {
    hprintln!("stepdamp-core on Cortex-M4F: patent-motor, three legs, {} periods per phase", PERIODS);
    let real = CurrentRipple { per_amp_d: &real_motor::RIPPLE_PER_AMP_D, per_amp_q: &real_motor::RIPPLE_PER_AMP_Q };
    for (title, prefix, ripple) in [(None, "", CurrentRipple::NONE), (Some("patent-motor-real"), "real-", real)] {
        if let Some(t) = title {
            hprintln!("with the current parts of {}: the same laws, {} periods per phase", t, PERIODS);
        }
        let mut hash = Fnv(0x811c_9dc5);
        let mut faults = 0;
        for (tag, law) in LAWS {
            faults += run((prefix, tag), ripple, law, &mut hash);
        }
        hprintln!("{}checksum fnv1a=0x{:08x} periods={} faults={}", prefix, hash.0, 3 * PERIODS, faults);
    }
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::bkpt();
    }
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::bkpt();
    }
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    hprintln!("hard fault: {:?}", ef);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::bkpt();
    }
}
