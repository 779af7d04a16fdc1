//! The report of a [`RippleFit`], as `stepdamp identify --accel` prints it.

use super::{Interval95, MIN_BLOCKS, NotIdentified, RippleFit};
use std::fmt;

impl fmt::Display for RippleFit {
    /// The head, the harmonics per direction with their intervals, what was left out, and the
    /// validation.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let h = &self.head;
        let iv =
            |i: Interval95, k: f64, p: usize| format!("{:.p$} [{:.p$}, {:.p$}]", k * i.value, k * i.low, k * i.high);
        writeln!(f, "head (95 % intervals):")?;
        writeln!(f, "  total inertia J_t  {} ×1e-5 kg·m²", iv(h.total_inertia_kg_m2, 1e5, 3))?;
        writeln!(f, "  carriage mass m    {} kg", iv(h.carriage_mass_kg, 1.0, 3))?;
        writeln!(f, "  belt mode          {} Hz", iv(h.belt_hz, 1.0, 1))?;
        writeln!(f, "  belt damping ratio {}", iv(h.belt_damping_ratio, 1.0, 3))?;
        writeln!(f, "  belt stiffness     {:.3e} N/m", h.belt_stiffness_n_per_m)?;
        writeln!(f, "  rotor damping c    {} ×1e-3 N·m·s/rad", iv(h.rotor_damping_nm_s_per_rad, 1e3, 3))?;
        writeln!(f, "  shift delay        {} µs", iv(h.shift_delay_s, 1e6, 1))?;
        let sign = if self.sensor_sign_fitted {
            "sign fitted"
        } else {
            "sign not told apart: no trial, or no fit with a drive's delay; taken as found"
        };
        writeln!(f, "  sensor gain        {:+.3} (printed per belt acceleration; {sign})", self.sensor_gain)?;
        writeln!(f, "ripple at the run current, torque on the rotor −A·sin(k·θe + φ):")?;
        for x in &self.harmonics {
            writeln!(
                f,
                "  {:<8} k={:>2}: A {} mN·m, φ {:+.3} ± {:.3} rad ({} blocks, {:.2}–{:.2} rev/s, {:.1} % explained)",
                x.direction.name(),
                x.order,
                iv(x.amplitude_nm, 1e3, 2),
                x.phase_rad.value,
                0.5 * (x.phase_rad.high - x.phase_rad.low),
                x.blocks,
                x.speeds_rev_s.0,
                x.speeds_rev_s.1,
                100.0 * x.explained_share
            )?;
        }
        // Runs of orders left out alike, one line each.
        let alike = |a: &NotIdentified, b: &NotIdentified| {
            a.direction == b.direction
                && a.blocks == b.blocks
                && a.band_limit_rev_s.is_some() == b.band_limit_rev_s.is_some()
        };
        for run in self.not_identified.chunk_by(alike) {
            let (first, last) = (&run[0], &run[run.len() - 1]);
            let orders = if run.len() == 1 {
                format!("k={}", first.order)
            } else {
                format!("k={}–{}", first.order, last.order)
            };
            let why = match (first.band_limit_rev_s, last.band_limit_rev_s) {
                (Some(a), Some(b)) if run.len() > 1 => format!(
                    "{} block(s) in band each (fewer than {MIN_BLOCKS}): they need speeds at or below {a:.2}…{b:.2} rev/s",
                    first.blocks
                ),
                _ => first.reason.clone(),
            };
            writeln!(f, "  {:<8} {orders}: not identified: {why}", first.direction.name())?;
        }
        write!(
            f,
            "validation: the model explains {:.1} % of the vibration at the motor's harmonics ({} blocks of {} captures)",
            100.0 * self.explained_share,
            self.blocks,
            self.captures
        )
    }
}
