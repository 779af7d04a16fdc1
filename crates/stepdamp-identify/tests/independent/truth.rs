//! What the tests compare the identified profiles with: the independent generators' true
//! motor as a profile (its ripple, or the whole motor as the plant of this repository's
//! simulator), and the per-harmonic ripple comparison.
//!
//! Not part of the generators: this is where their output meets `stepdamp-profile` (its
//! `ripple` of the true profile is checked against the generator's own DFT, two codes for
//! one physics).

use super::flux::FluxShape;
use super::servo_real::RealMotor;
use super::{Friction, open_loop};
use stepdamp_profile::data::{FrictionLawName, FrictionSection};
use stepdamp_profile::flux::{FluxHarmonic, FluxSection};
use stepdamp_profile::ripple::{Ripple, ripple};
use stepdamp_profile::{DetentTerm, Profile};

/// The operating points of the real-motor acceptance: name, `i_d` per unit of `I_hold`,
/// `i_q` (A).
pub const POINTS: [(&str, f64, f64); 3] =
    [("open loop I_hold", 1.0, 0.0), ("open loop I_hold/2", 0.5, 0.0), ("servo iq 0.5 A", 0.0, 0.5)];

/// `base` holding a generator's true detent `(order, A N·m, φ rad)` and flux shape.
pub fn truth_profile(base: &Profile, detent: &[(u16, f64, f64)], flux: &FluxShape) -> Profile {
    base.edited("truth", |d| {
        d.motor.detent = detent
            .iter()
            .map(|&(order, amplitude_nm, phase_rad)| DetentTerm { order, amplitude_nm, phase_rad })
            .collect();
        d.motor.flux = FluxSection {
            phase_b_gain: flux.g,
            harmonics: flux
                .harmonics
                .iter()
                .map(|&(order, ratio, phase_rad)| FluxHarmonic { order, ratio, phase_rad })
                .collect(),
        };
    })
    .unwrap()
}

/// The servo generator's whole true motor `m` as a profile, for the plant of this
/// repository's simulator: `base` (its drive) holding `m`'s detent and flux
/// ([`truth_profile`]), winding, `Km`, `J`, `D`, `Fs` and friction law (smooth creep, or
/// Stribeck with the same creep speed: the same formulas as `stepdamp-sim`'s laws).
pub fn servo_plant(base: &Profile, m: &RealMotor) -> Profile {
    let mech = &m.mech;
    let friction = match mech.friction {
        Friction::SmoothCreep => FrictionSection {
            law: FrictionLawName::Smooth,
            creep_speed_rad_s: Some(mech.creep_rad_s),
            ..FrictionSection::default()
        },
        Friction::Stribeck { fs_static_nm, stribeck_rad_s } => FrictionSection {
            law: FrictionLawName::Stribeck,
            creep_speed_rad_s: Some(mech.creep_rad_s),
            static_nm: Some(fs_static_nm),
            stribeck_speed_rad_s: Some(stribeck_rad_s),
        },
    };
    let (winding, rotor) = ((m.r, m.l, mech.km), (mech.j, mech.d, mech.fs));
    with_mechanics(&truth_profile(base, &mech.detent, &m.flux), winding, rotor, friction)
}

/// The open-loop generator's whole true motor `m` as a profile, for the plant of this
/// repository's simulator: `base` (its drive) holding `m`'s detent and flux
/// ([`truth_profile`]), winding, `Km`, `J`, `D`, `Fs` and friction law (Karnopp, or smooth
/// with its creep speed).
pub fn open_loop_plant(base: &Profile, m: &open_loop::Motor) -> Profile {
    let friction = match m.friction {
        open_loop::Friction::Karnopp => FrictionSection::default(),
        open_loop::Friction::Smooth { creep_rad_s } => FrictionSection {
            law: FrictionLawName::Smooth,
            creep_speed_rad_s: Some(creep_rad_s),
            ..FrictionSection::default()
        },
    };
    with_mechanics(&truth_profile(base, &m.detent, &m.flux), (m.r, m.l, m.km), (m.j, m.d, m.fs), friction)
}

/// `truth` with winding `(R Ω, L H, Km N·m/A)`, rotor `(J kg·m², D N·m·s/rad, Fs N·m)` and
/// `friction`.
fn with_mechanics(
    truth: &Profile,
    winding: (f64, f64, f64),
    rotor: (f64, f64, f64),
    friction: FrictionSection,
) -> Profile {
    truth
        .edited("truth", |d| {
            (d.motor.resistance_ohm, d.motor.inductance_h, d.motor.km_nm_per_a) = winding;
            (d.motor.inertia_kg_m2, d.motor.viscous_nm_s_per_rad, d.motor.coulomb_friction_nm) = rotor;
            d.motor.friction = friction;
        })
        .unwrap()
}

/// `A·e^{jφ}` as `(re, im)`.
pub fn z(a: f64, p: f64) -> (f64, f64) {
    (a * p.cos(), a * p.sin())
}

/// The worst harmonic error of `id`'s ripple at rotor-frame currents `(i_d, i_q)` (A)
/// against the generator's own ripple there, `own` (`(order, A, φ)`, torque on the rotor
/// `−Σ A sin(k·θe + φ)`), as a fraction of the tolerance max(10 %, 1 mN·m) (complex
/// difference), with where it is (`what`: the operating point's name). Panics when `own`
/// differs from `stepdamp_profile::ripple` of `truth` by 1e-9 N·m or more (a convention
/// mismatch between the generator and the library).
pub fn ripple_error(
    own: &[(u16, f64, f64)],
    truth: &Profile,
    id: &Profile,
    i_d: f64,
    i_q: f64,
    what: &str,
) -> (f64, String) {
    let (lib, got) = (ripple(truth, i_d, i_q).unwrap(), ripple(id, i_d, i_q).unwrap());
    let find = |r: &Ripple, k: u16| {
        r.harmonics.iter().find(|x| x.order == k).map_or((0.0, 0.0), |x| z(x.amplitude_nm, x.phase_rad))
    };
    let mut worst = (0.0, String::new());
    for &(k, a, p) in own {
        let (t, l, i) = (z(a, p), find(&lib, k), find(&got, k));
        assert!((t.0 - l.0).hypot(t.1 - l.1) < 1e-9, "{what}, order {k}: generator {t:?}, stepdamp_profile {l:?}");
        let err = (t.0 - i.0).hypot(t.1 - i.1) / (0.1 * a).max(1e-3);
        if err > worst.0 {
            worst = (err, format!("{what}, order {k}: {:.2} mN·m, identified {:.2}", 1e3 * a, 1e3 * i.0.hypot(i.1)));
        }
    }
    worst
}
