//! Wave tables that turn the current vector by `ε·sin(H·θe)` rad, for the accelerometer route
//! on a Klipper printer: a **trial** of known shift, so that a log recorded with it gives the
//! route its scale (`stepdamp identify --accel … --klipper-trial LOG=H,U,0`,
//! `docs/accelerometer.md#a-trial-table-for-klipper`), and the **correction** an influence
//! step asks for (`docs/accelerometer.md#refining-a-trinamic-table`).
//!
//! The table is [`super::quarter_wave`] with `ε = U` at order `H = 4j`: only orders 4, 8, 12
//! and 16 with phase 0 (or π: a negative `U`) can be expressed (module doc of [`super`]).
//! **Frame.** Klipper's log gives the angle `2π·(p + mcu_phase_offset)/(4·microsteps)`, which is
//! `−2π·MSCNT/1024` for a stepper whose `dir_pin` is not inverted (`tmc.py:435–436` takes
//! `1023 − MSCNT`) and `+2π·MSCNT/1024` otherwise. An odd shift `U·sin(Hθ)` reads the same in
//! both frames (the mirror `θ → −θ` also turns the shift's sign), so the trial is `H,U,0` in
//! the log whichever way the stepper is wired.

use super::{FULL_SCALE, TmcRegisters, encode, klipper_section, order_parts, quarter_wave};
use crate::ExportError;

/// The smallest trial shift written (rad): 4 counts of [`FULL_SCALE`] on the third and fifth
/// harmonics of the wave together, so that the table's rounding (half a count per entry)
/// stays a few per cent of the trial; the achieved shift is computed from the integer table
/// anyway ([`ShiftTable::achieved_rad`]).
pub const MIN_TRIAL_SHIFT_RAD: f64 = 4.0 / FULL_SCALE as f64;

/// The largest trial shift asked (rad): 0.25 rad, about twice the Prusa route's largest
/// planned trial (`M973 … C0.03`, 0.12 rad of shift). The registers hold less: at order 4
/// about 0.18 rad, at 8 0.04, at 12 and 16 0.02 (their four step-width segments); beyond,
/// [`ShiftTable::new`] refuses the encoding.
pub const MAX_TRIAL_SHIFT_RAD: f64 = 0.25;

/// `harmonic` as a table order: one of 4, 8, 12, 16 (what a Trinamic table turns), or the
/// one-line refusal.
pub fn check_order(harmonic: u32) -> Result<u16, ExportError> {
    match u16::try_from(harmonic) {
        Ok(h) if h % 4 == 0 && (4..=16).contains(&h) => Ok(h),
        _ => Err(ExportError::Invalid(format!(
            "shift order {harmonic}: a Trinamic table turns the current only at orders 4, 8, 12, 16 (sine phase)"
        ))),
    }
}

/// A table turning the current vector by `ε·sin(H·θe)`, and the shift it makes: a trial
/// ([`ShiftTable::trial`]) or a correction ([`ShiftTable::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShiftTable {
    /// The order `H` (4, 8, 12 or 16).
    pub harmonic: u16,
    /// The shift asked for, `ε` (rad; the sign is the phase: negative is `PHI = π`).
    pub shift_rad: f64,
    /// The shift the integer table makes: the sine part of order `H` of its q current per
    /// unit of run current (rad; [`super::order_parts`]), what `--klipper-trial` should say.
    pub achieved_rad: f64,
    /// The largest other part the table makes at orders 1–16, its cosine part at `H`
    /// included (rad): rounding, a few thousandths of a radian.
    pub stray_rad: f64,
    /// The registers.
    pub registers: TmcRegisters,
}

impl ShiftTable {
    /// The table turning the current vector by `shift_rad·sin(harmonic·θe)` (a correction:
    /// any magnitude up to [`MAX_TRIAL_SHIFT_RAD`], 0 included). Refuses an order the table
    /// cannot carry, a shift not finite or beyond that, and a wave the registers cannot
    /// encode.
    pub fn new(harmonic: u16, shift_rad: f64) -> Result<Self, ExportError> {
        check_order(u32::from(harmonic))?;
        if !(shift_rad.is_finite() && shift_rad.abs() <= MAX_TRIAL_SHIFT_RAD) {
            return Err(ExportError::Invalid(format!(
                "shift {shift_rad} rad: its magnitude must be at most {MAX_TRIAL_SHIFT_RAD} rad"
            )));
        }
        let q = quarter_wave(&[(harmonic / 4, shift_rad)]);
        let registers = encode(&q).map_err(|e| {
            ExportError::Invalid(format!(
                "shift {harmonic},{shift_rad}: the table cannot hold it ({e}): a smaller shift (order 4 holds about 0.18 rad, 8 0.04, 12 and 16 0.02)"
            ))
        })?;
        let q = registers.decode();
        let (achieved_rad, cos_h) = order_parts(&q, harmonic);
        let stray_rad = (1..=16u16)
            .filter(|&k| k != harmonic)
            .map(|k| {
                let (s, c) = order_parts(&q, k);
                s.hypot(c)
            })
            .fold(cos_h.abs(), f64::max);
        Ok(ShiftTable { harmonic, shift_rad, achieved_rad, stray_rad, registers })
    }

    /// A **trial** table: [`Self::new`] with the shift's magnitude at least
    /// [`MIN_TRIAL_SHIFT_RAD`], so that its change stands out of the table's rounding.
    pub fn trial(harmonic: u16, shift_rad: f64) -> Result<Self, ExportError> {
        if !(shift_rad.is_finite() && (MIN_TRIAL_SHIFT_RAD..=MAX_TRIAL_SHIFT_RAD).contains(&shift_rad.abs())) {
            return Err(ExportError::Invalid(format!(
                "trial shift {shift_rad} rad: its magnitude must be in {MIN_TRIAL_SHIFT_RAD:.4}..={MAX_TRIAL_SHIFT_RAD} rad"
            )));
        }
        Self::new(harmonic, shift_rad).map_err(|e| ExportError::Invalid(format!("trial: {e}")))
    }

    /// What `stepdamp identify --accel --klipper-trial` takes for a log recorded with this
    /// table: `H,U,PHI` with `U` the achieved shift's magnitude (4 decimals) and `PHI` 0, or π
    /// (8 decimals) for a negative shift.
    pub fn klipper_trial_arg(&self) -> String {
        let phase = if self.achieved_rad < 0.0 { "3.14159265" } else { "0" };
        format!("{},{:.4},{phase}", self.harmonic, self.achieved_rad.abs())
    }
}

/// The Klipper config block of a trial table for a stepper (`axis` as
/// [`super::klipper_section`] checks it), ASCII only: comments that say what it does, how to
/// load and unload it (an `[include]`: Klipper's parser is `strict=False`, configfile.py:172,
/// so a repeated section merges, later options winning), and what to tell stepdamp; then
/// the section and its `driver_…` lines.
pub fn trial_block(t: &ShiftTable, axis: &str) -> Result<String, ExportError> {
    let section = klipper_section(axis)?;
    let mut s = format!(
        "# Trial wave table from stepdamp: turns the current vector by {:.4}*sin({}*theta_e) rad\n\
         # (asked {:.4}; other orders within {:.4} rad, the table's rounding).\n",
        t.achieved_rad, t.harmonic, t.shift_rad, t.stray_rad
    );
    s += "# Add [include <this file>] to printer.cfg after the driver's section (Klipper merges\n\
          # the options into it, overriding any driver_MSLUT*/W*/X*/START_SIN* there),\n\
          # FIRMWARE_RESTART, record the trial log, then remove the include and FIRMWARE_RESTART.\n";
    s += &format!("# Then: stepdamp identify --accel ... --klipper-trial TRIAL_LOG={}\n", t.klipper_trial_arg());
    s += &format!("[{section}]\n");
    Ok(s + &t.registers.klipper_lines())
}

/// The Klipper config block of a correction table (`accel klipper-refine`): `notes` (the step
/// that gave it, any lines) as `#` comments made ASCII (each line escaped to one printable
/// line, `²` as `^2`: Klipper reads the file in the locale's encoding), what the table does and
/// how to load it (as [`trial_block`]), then the section and its `driver_…` lines.
pub fn shift_block(t: &ShiftTable, axis: &str, notes: &str) -> Result<String, ExportError> {
    let section = klipper_section(axis)?;
    let mut s = String::new();
    for line in notes.lines() {
        let ascii: String = crate::escape::line(&line.replace('²', "^2"))
            .chars()
            .map(|c| if c.is_ascii() { c.to_string() } else { c.escape_unicode().to_string() })
            .collect();
        s += &format!("# {ascii}\n");
    }
    s += &format!(
        "# Wave table from stepdamp: turns the current vector by {:.4}*sin({}*theta_e) rad\n\
         # (asked {:.4}; other orders within {:.4} rad, the table's rounding).\n",
        t.achieved_rad, t.harmonic, t.shift_rad, t.stray_rad
    );
    s += "# Add [include <this file>] to printer.cfg after the driver's section (Klipper merges\n\
          # the options into it, overriding any driver_MSLUT*/W*/X*/START_SIN* there), FIRMWARE_RESTART.\n";
    s += &format!("[{section}]\n");
    Ok(s + &t.registers.klipper_lines())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tmc::{parse_klipper, table};
    use std::f64::consts::TAU;

    #[test]
    fn a_trial_table_turns_the_current_vector_by_the_shift_asked() {
        for (h, u) in [(4, 0.12), (4, -0.05), (4, 0.18), (8, 0.04), (12, 0.02), (16, -0.02)] {
            let t = ShiftTable::trial(h, u).unwrap();
            assert!((t.achieved_rad / u - 1.0).abs() < 0.03, "{h},{u}: {t:?}");
            assert!(t.stray_rad < 0.004, "{h},{u}: {t:?}");
            // The coil currents the core replays: the vector's angle minus θe is the shift.
            let r = table(&t.registers);
            let mut worst: f64 = 0.0;
            for m in 0..1024 {
                let th = TAU * m as f64 / 1024.0;
                let [a, b] = r.forward[m];
                let turned = f64::from(b).atan2(f64::from(a)) - th;
                let turned = (turned + TAU / 2.0).rem_euclid(TAU) - TAU / 2.0;
                worst = worst.max((turned - u * (f64::from(h) * th).sin()).abs());
            }
            assert!(worst < 0.012, "{h},{u}: {worst} rad from the shift asked");
        }
    }

    #[test]
    fn the_block_reads_back_to_the_same_registers_and_names_the_trial_argument() {
        let t = ShiftTable::trial(4, 0.12).unwrap();
        let b = trial_block(&t, "tmc5160 stepper_x").unwrap();
        assert_eq!(parse_klipper(&b, "trial.cfg").unwrap(), t.registers);
        assert!(b.contains(&format!("--klipper-trial TRIAL_LOG={}", t.klipper_trial_arg())), "{b}");
        assert!(b.contains("[tmc5160 stepper_x]\n") && b.is_ascii(), "{b}");
        let notes = "harmonic 4: 1.2 m/s² \u{1b}[31m\nsecond line é";
        let c = shift_block(&t, "tmc5160 stepper_x", notes).unwrap();
        assert!(c.is_ascii() && c.starts_with("# harmonic 4: 1.2 m/s^2 \\x1b[31m\n# second line \\u{e9}\n"), "{c}");
        assert_eq!(parse_klipper(&c, "c.cfg").unwrap(), t.registers);
        let neg = ShiftTable::trial(4, -0.05).unwrap();
        assert_eq!(neg.klipper_trial_arg(), format!("4,{:.4},3.14159265", -neg.achieved_rad));
    }

    #[test]
    fn orders_and_shifts_the_table_cannot_carry_are_refused_with_the_range() {
        for (h, u) in [
            (2, 0.1),
            (1, 0.1),
            (20, 0.1),
            (0, 0.1),
            (4, 0.001),
            (4, 0.3),
            (12, 0.05),
            (8, 0.1),
            (4, f64::NAN),
            (4, f64::INFINITY),
        ] {
            let e = ShiftTable::trial(h, u).unwrap_err().to_string();
            assert!(e.contains("trial") && !e.contains('\n'), "{h},{u}: {e}");
        }
        let e = trial_block(&ShiftTable::trial(4, 0.1).unwrap(), "tmc2209 stepper_x").unwrap_err().to_string();
        assert!(e.contains("no wave table"), "{e}");
    }
}
