//! Friction laws of the plant, as pure functions of the speed.
//!
//! Sign convention: the friction torque *on the rotor* is `−friction_nm(ω)`, i.e. the
//! functions return the torque that opposes the motion, positive for `ω > 0`. The viscous
//! part `D·ω` is not included (the plant adds it as today).
//!
//! | law | torque opposing the motion | profile keys (`[motor.friction]`, ranges checked by the profile crate) |
//! |---|---|---|
//! | [`FrictionLaw::Karnopp`] (today's) | `Fs·sgn(ω)` when moving; holds up to `Fs` at rest (the plant's stick logic) | `coulomb_friction_nm` |
//! | [`FrictionLaw::SmoothCoulomb`] | `Fs·tanh(ω/ω_ε)`: no sticking, the rotor creeps at `|ω| ≲ ω_ε` under torques below `Fs` | `friction.law = "smooth"`, `friction.creep_speed_rad_s` |
//! | [`FrictionLaw::Stribeck`] | `(Fs + (Fs_static − Fs)·exp(−(ω/ω_s)²))·tanh(ω/ω_ε)`: break-away `Fs_static > Fs` decaying to `Fs` over the Stribeck speed `ω_s` | `friction.law = "stribeck"`, `friction.static_nm`, `friction.stribeck_speed_rad_s`, `friction.creep_speed_rad_s` |
//!
//! The Karnopp law is discontinuous at `ω = 0` and needs the plant's stick state; the other
//! two are smooth and only need an integrator that is stable for their slope at zero speed,
//! `Fs_static/ω_ε` (N·m·s/rad): an explicit step `h` is stable for `h < 2·J·ω_ε/Fs_static`,
//! so the plant sub-steps them (see [`FrictionLaw::max_slope`] and [`crate::lanes`]).

/// A friction law (the Coulomb level `Fs` is the profile's `coulomb_friction_nm`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrictionLaw {
    /// Today's: `Fs·sgn(ω)` when moving, stick at rest (handled by the plant).
    Karnopp,
    /// `Fs·tanh(ω/ω_ε)`.
    SmoothCoulomb {
        /// Creep speed `ω_ε`, rad/s (> 0).
        creep_speed_rad_s: f64,
    },
    /// Stribeck with a smooth sign.
    Stribeck {
        /// Break-away torque `Fs_static ≥ Fs`, N·m.
        static_nm: f64,
        /// Stribeck speed `ω_s`, rad/s (> 0).
        stribeck_speed_rad_s: f64,
        /// Creep speed `ω_ε`, rad/s (> 0).
        creep_speed_rad_s: f64,
    },
}

impl FrictionLaw {
    /// The friction torque opposing the motion at speed `omega` (rad/s), N·m, for Coulomb
    /// level `fs_nm`. Karnopp returns `Fs·sgn(ω)` (0 at rest: the plant's stick logic
    /// decides the torque there).
    pub fn friction_nm(&self, fs_nm: f64, omega: f64) -> f64 {
        match *self {
            FrictionLaw::Karnopp => {
                if omega > 0.0 {
                    fs_nm
                } else if omega < 0.0 {
                    -fs_nm
                } else {
                    0.0
                }
            }
            FrictionLaw::SmoothCoulomb { creep_speed_rad_s } => fs_nm * (omega / creep_speed_rad_s).tanh(),
            FrictionLaw::Stribeck { static_nm, stribeck_speed_rad_s, creep_speed_rad_s } => {
                let level = fs_nm + (static_nm - fs_nm) * (-(omega / stribeck_speed_rad_s).powi(2)).exp();
                level * (omega / creep_speed_rad_s).tanh()
            }
        }
    }

    /// Largest slope `dF/dω` of the smooth laws, N·m·s/rad (`Fs_static/ω_ε`, at zero
    /// speed); `None` for Karnopp. An explicit integration step must be shorter than
    /// `2·J / max_slope`.
    pub fn max_slope(&self, fs_nm: f64) -> Option<f64> {
        match *self {
            FrictionLaw::Karnopp => None,
            FrictionLaw::SmoothCoulomb { creep_speed_rad_s } => Some(fs_nm / creep_speed_rad_s),
            FrictionLaw::Stribeck { static_nm, creep_speed_rad_s, .. } => Some(static_nm / creep_speed_rad_s),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const SMOOTH: FrictionLaw = FrictionLaw::SmoothCoulomb { creep_speed_rad_s: 0.01 };
    const STRIBECK: FrictionLaw =
        FrictionLaw::Stribeck { static_nm: 0.015, stribeck_speed_rad_s: 0.05, creep_speed_rad_s: 0.005 };

    #[test]
    fn every_law_tends_to_coulomb_at_speed_and_the_smooth_ones_vanish_at_rest() {
        for law in [FrictionLaw::Karnopp, SMOOTH, STRIBECK] {
            assert!((law.friction_nm(0.01, 1.0) - 0.01).abs() < 1e-9, "{law:?}");
            assert!((law.friction_nm(0.01, -1.0) + 0.01).abs() < 1e-9, "{law:?}");
            assert_eq!(law.friction_nm(0.01, 0.0), 0.0);
        }
    }

    #[test]
    fn stribeck_breaks_away_above_coulomb_and_decays_over_its_speed() {
        // Just past the creep region, well inside the Stribeck speed: near Fs_static.
        let near = STRIBECK.friction_nm(0.01, 0.02);
        assert!(near > 0.0135 && near < 0.015, "{near}");
        // At three Stribeck speeds the excess is exp(−9) of (Fs_static − Fs).
        let far = STRIBECK.friction_nm(0.01, 0.15);
        assert!((far - 0.01 - 0.005 * (-9.0f64).exp()).abs() < 1e-9, "{far}");
    }

    #[test]
    fn smooth_coulomb_creeps_linearly_below_its_creep_speed() {
        // tanh(x) = x − x³/3 + …: F ≈ Fs·ω/ω_ε within x²/3 = 3.3e-5 at ω = ω_ε/100.
        let f = SMOOTH.friction_nm(0.01, 1e-4);
        let linear = 0.01 * 1e-4 / 0.01;
        assert!((f / linear - 1.0).abs() < 4e-5, "{f}");
        assert_eq!(SMOOTH.max_slope(0.01), Some(1.0));
    }

    proptest! {
        #[test]
        fn friction_is_odd_and_bounded_by_the_break_away_torque(w in -10.0f64..10.0) {
            for law in [SMOOTH, STRIBECK] {
                let f = law.friction_nm(0.01, w);
                prop_assert!((f + law.friction_nm(0.01, -w)).abs() < 1e-15);
                prop_assert!(f.abs() <= 0.015 + 1e-15);
                prop_assert!(f * w >= 0.0, "friction opposes the motion");
            }
        }
    }
}
