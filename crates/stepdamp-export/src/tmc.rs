//! Trinamic microstep table, written as a Klipper `[tmc5160 stepper_x]`-style block
//! (`driver_MSLUT0` … `driver_START_SIN90`). Klipper writes the wave table only for the
//! sections in [`WAVE_TABLE_DRIVERS`] (`TMCWaveTableHelper` is called from `tmc2130.py`,
//! `tmc2240.py` and `tmc5160.py`, nowhere else); any other section refuses the options.
//!
//! Registers (datasheet and Klipper's `tmc2130.py`/`tmc5160.py` field masks):
//! `MSLUT0..7` (0x60–0x67): bit `x` (MSLUT0 bit 0 = bit 0 … MSLUT7 bit 31 = bit 255) is the
//! step from quarter-wave entry `x` to `x+1`: `base(W) + bit` with `base = −1, 0, +1, +2`
//! for `W = 0..3`. `MSLUTSEL` (0x68): `W0` bits 0–1 … `W3` bits 6–7, `X1` bits 8–15, `X2`
//! 16–23, `X3` 24–31; entry steps `x < X1` use `W0`, `X1 ≤ x < X2` `W1`, `X2 ≤ x < X3` `W2`,
//! the rest `W3`. `MSLUTSTART` (0x69): `START_SIN` bits 0–7 (entry 0, `CUR_A` at
//! `MSCNT = 0`), `START_SIN90` bits 16–23 (`CUR_B` at `MSCNT = 0`, entry 256).
//! Klipper's default registers decode, by this reading, to `round(248·sin(2π(x−½)/1024))`
//! at all entries 1…256 (a test checks it).
//!
//! The wave over `MSCNT = m` in 0..1024: `Q[m]` for m ≤ 256, mirrored `Q[512−m]` up to 512,
//! negated for the second half; `CUR_A = w(m)`, `CUR_B = w(m+256)`. Such a wave holds odd
//! sine harmonics only, and (stepdamp winding a on coil B, b on coil A) the q current it
//! makes is `Σ_j (c_{4j−1} + c_{4j+1}) sin(4jθe)`: only the **sine part of orders 4, 8, 12…**
//! of the correction can be expressed, nothing of orders 1, 2, 3, 5, 6, 7.

use crate::{Correction, ExportError, RunCurrent};
use serde::Serialize;
use std::f64::consts::TAU;
use stepdamp_core::{CorrectionTable, TABLE_TICKS};
use stepdamp_sim::Profile;
use stepdamp_sim::profile::DetentTerm;

mod refine;
mod shift;
pub use refine::{KlipperRefined, klipper_refine, table_in_use};
pub use shift::{MAX_TRIAL_SHIFT_RAD, MIN_TRIAL_SHIFT_RAD, ShiftTable, check_order, shift_block, trial_block};

/// The Klipper driver sections that accept `driver_MSLUT0` … `driver_START_SIN90`: the
/// modules that call `TMCWaveTableHelper` (Klipper `klippy/extras/tmc.py`, at the commit
/// named in `docs/exporters.md`). Klipper has no `tmc2160` or `tmc5130` section; the
/// `tmc2208`, `tmc2209` and `tmc2660` sections refuse the options at start-up.
pub const WAVE_TABLE_DRIVERS: [&str; 3] = ["tmc2130", "tmc2240", "tmc5160"];

/// Largest length of a Klipper section name `--axis` may give, characters.
pub const SECTION_MAX: usize = 80;

/// Checks a Klipper section name for the table (`"tmc5160 stepper_x"`): a driver of
/// [`WAVE_TABLE_DRIVERS`] and one or more stepper-name words of `[A-Za-z0-9_]`
/// (`stepper_x`, `extruder1`, `manual_stepper my_belt`), single spaces, at most
/// [`SECTION_MAX`] characters. Returns the section as written between `[` and `]`.
pub fn klipper_section(axis: &str) -> Result<String, ExportError> {
    let words: Vec<&str> = axis.split(' ').collect();
    let shown = crate::escape::line(axis);
    let ok_word = |w: &str| !w.is_empty() && w.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if axis.len() > SECTION_MAX || words.len() < 2 || !words.iter().all(|w| ok_word(w)) {
        return Err(ExportError::Invalid(format!(
            "--axis \"{shown}\": a Klipper section \"<driver> <stepper>\" such as \"tmc5160 stepper_x\" \
             (words of letters, digits and _, single spaces, at most {SECTION_MAX} characters)"
        )));
    }
    if !WAVE_TABLE_DRIVERS.contains(&words[0]) {
        return Err(ExportError::Invalid(format!(
            "--axis \"{shown}\": Klipper's {} section has no wave table (it would refuse driver_MSLUT0 at \
             start-up); the sections that take one are {}",
            words[0],
            WAVE_TABLE_DRIVERS.join(", ")
        )));
    }
    Ok(words.join(" "))
}

/// Amplitude the table is scaled to (the default table's peak: 248 counts = the run current).
pub const FULL_SCALE: i16 = 248;

/// The registers of a microstep table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct TmcRegisters {
    /// `MSLUT0..7`.
    pub mslut: [u32; 8],
    /// `W0..W3` (0..=3).
    pub w: [u8; 4],
    /// `X1..X3`.
    pub x: [u8; 3],
    /// `START_SIN`.
    pub start_sin: u8,
    /// `START_SIN90`.
    pub start_sin90: u8,
}

impl TmcRegisters {
    /// Klipper's defaults (`TMCWaveTableHelper`), the chip's reset table.
    pub const KLIPPER_DEFAULT: TmcRegisters = TmcRegisters {
        mslut: [0xAAAAB554, 0x4A9554AA, 0x24492929, 0x10104222, 0xFBFFFFFF, 0xB5BB777D, 0x49295556, 0x00404222],
        w: [2, 1, 1, 1],
        x: [128, 255, 255],
        start_sin: 0,
        start_sin90: 247,
    };

    /// `MSLUTSEL` (0x68) as one word.
    pub fn mslutsel(&self) -> u32 {
        let w = self.w.iter().enumerate().fold(0u32, |a, (i, &w)| a | (u32::from(w & 3) << (2 * i)));
        w | u32::from(self.x[0]) << 8 | u32::from(self.x[1]) << 16 | u32::from(self.x[2]) << 24
    }

    /// `MSLUTSTART` (0x69) as one word.
    pub fn mslutstart(&self) -> u32 {
        u32::from(self.start_sin) | u32::from(self.start_sin90) << 16
    }

    /// The quarter wave `Q[0..=256]` the registers define.
    pub fn decode(&self) -> [i32; 257] {
        let mut q = [0i32; 257];
        q[0] = i32::from(self.start_sin);
        for x in 0..256 {
            let bit = (self.mslut[x / 32] >> (x % 32)) & 1;
            let seg = if x < usize::from(self.x[0]) {
                0
            } else if x < usize::from(self.x[1]) {
                1
            } else if x < usize::from(self.x[2]) {
                2
            } else {
                3
            };
            q[x + 1] = q[x] + i32::from(self.w[seg] & 3) - 1 + bit as i32;
        }
        q
    }

    /// The Klipper config lines (`driver_MSLUT0: …` … `driver_START_SIN90: …`).
    pub fn klipper_lines(&self) -> String {
        let mut s = String::new();
        for (i, v) in self.mslut.iter().enumerate() {
            s += &format!("driver_MSLUT{i}: {v}\n");
        }
        for (i, v) in self.w.iter().enumerate() {
            s += &format!("driver_W{i}: {v}\n");
        }
        for (i, v) in self.x.iter().enumerate() {
            s += &format!("driver_X{}: {v}\n", i + 1);
        }
        s += &format!("driver_START_SIN: {}\ndriver_START_SIN90: {}\n", self.start_sin, self.start_sin90);
        s
    }
}

/// Encodes a quarter wave `Q[0..=256]` (each in 0..=255): steps `Q[x+1] − Q[x]` in −1..=3,
/// in at most four segments whose steps span two adjacent values, and `START_SIN90 = Q[256]`.
pub fn encode(q: &[i32; 257]) -> Result<TmcRegisters, ExportError> {
    if let Some(i) = q.iter().position(|&v| !(0..=255).contains(&v)) {
        return Err(ExportError::Invalid(format!("quarter-wave entry {i} = {}: must be in 0..=255", q[i])));
    }
    let d: Vec<i32> = (0..256).map(|x| q[x + 1] - q[x]).collect();
    // Greedy maximal segments: each holds steps within {lo, lo+1}.
    let mut segs: Vec<(usize, i32)> = Vec::new(); // (start, lo)
    let (mut start, mut lo, mut hi) = (0usize, d[0], d[0]);
    for (x, &s) in d.iter().enumerate().skip(1) {
        let (nlo, nhi) = (lo.min(s), hi.max(s));
        if nhi - nlo > 1 {
            segs.push((start, lo));
            (start, lo, hi) = (x, s, s);
        } else {
            (lo, hi) = (nlo, nhi);
        }
    }
    segs.push((start, lo));
    if segs.len() > 4 {
        return Err(ExportError::Invalid(format!(
            "the quarter wave needs {} step-width segments, the table has 4",
            segs.len()
        )));
    }
    let mut w = [1u8; 4];
    let mut x = [255u8; 3];
    for (i, &(st, lo)) in segs.iter().enumerate() {
        // A segment whose steps are all 3 needs W = 3 with bit 1; one of all −1, W = 0.
        let base = lo.clamp(-1, 2);
        if !(-1..=3).contains(&lo)
            || d[st..segs.get(i + 1).map_or(256, |s| s.0)].iter().any(|&v| v - base > 1 || v < base)
        {
            return Err(ExportError::Invalid(format!("step {lo} at entry {st} is outside −1..=3")));
        }
        w[i] = (base + 1) as u8;
        if i > 0 {
            x[i - 1] = st as u8;
        }
    }
    // Unused borders stay at 255 (the last step, x = 255, then uses the last used W).
    for i in segs.len()..4 {
        w[i] = w[segs.len() - 1];
    }
    let mut mslut = [0u32; 8];
    for (xi, &s) in d.iter().enumerate() {
        let seg = segs.iter().rposition(|&(st, _)| st <= xi).unwrap_or(0);
        let bit = s - (i32::from(w[seg]) - 1);
        if bit == 1 {
            mslut[xi / 32] |= 1 << (xi % 32);
        }
    }
    // Border 255 means "the last step uses the previous W": with 4 segments a border at 255
    // is ambiguous, so check the whole table decodes back.
    let regs = TmcRegisters { mslut, w, x, start_sin: q[0] as u8, start_sin90: q[256] as u8 };
    if regs.decode() != *q {
        return Err(ExportError::Invalid("the quarter wave does not fit the segment borders".into()));
    }
    Ok(regs)
}

/// The wave `w(m)` over `MSCNT = m` from a quarter wave.
pub fn wave(q: &[i32; 257], m: usize) -> i32 {
    let m = m % 1024;
    let h = m % 512;
    let v = if h <= 256 { q[h] } else { q[512 - h] };
    if m < 512 { v } else { -v }
}

/// Per-order coverage of the correction by a table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OrderCoverage {
    /// Harmonic order k.
    pub order: u16,
    /// Amplitude of the wanted compensating current, A.
    pub wanted_a: f64,
    /// Amplitude of the q current of this order the table makes, A.
    pub achieved_a: f64,
    /// Amplitude of what is left (`wanted − achieved`, as phasors), A.
    pub residual_a: f64,
    /// Whether a mirrored quarter wave can carry any of this order (k a multiple of 4).
    pub expressible: bool,
}

impl OrderCoverage {
    /// Predicted reduction of this order's ripple, dB: `20·log10(wanted/residual)`.
    pub fn reduction_db(&self) -> f64 {
        20.0 * (self.wanted_a / self.residual_a.max(1e-12)).log10()
    }

    /// Share of the wanted current the table carries: `1 − residual/wanted` (0 when nothing).
    pub fn carried_share(&self) -> f64 {
        (1.0 - self.residual_a / self.wanted_a.max(1e-300)).max(0.0)
    }
}

/// A table and how much of the model's ripple it carries.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TmcExport {
    /// The registers.
    pub registers: TmcRegisters,
    /// Per order of the model.
    pub coverage: Vec<OrderCoverage>,
    /// Share of the model's ripple power (Σ wanted²) the table removes: `1 − Σ residual²/Σ wanted²`.
    pub power_share: f64,
}

/// The quarter wave `Q[0..=256]` in counts of [`FULL_SCALE`] (rounded) of
/// `sin φ + Σ_j (ε_j/2)(sin(4j−1)φ + sin(4j+1)φ)` for `eps` = `(j, ε_j)`: coil currents
/// `(cos, sin)(θe + Σ_j ε_j sin 4jθe)` to first order in ε, i.e. the current vector turned by
/// `Σ_j ε_j sin(4j·θe)` rad (`docs/exporters.md#trinamic-microstep-table-through-klipper`).
pub fn quarter_wave(eps: &[(u16, f64)]) -> [i32; 257] {
    let w = |phi: f64| {
        phi.sin()
            + eps
                .iter()
                .map(|&(j, e)| e / 2.0 * (((4 * j - 1) as f64 * phi).sin() + ((4 * j + 1) as f64 * phi).sin()))
                .sum::<f64>()
    };
    let mut q = [0i32; 257];
    for (x, v) in q.iter_mut().enumerate() {
        *v = (f64::from(FULL_SCALE) * w(TAU * x as f64 / 1024.0)).round() as i32;
    }
    q
}

/// Builds the table for a correction: the wave `I·[sin φ + Σ_j (ε_j/2)(sin(4j−1)φ + sin(4j+1)φ)]`
/// with `ε_j` the sine part of order `4j` divided by `I`, in counts of [`FULL_SCALE`].
/// Refuses when no order of the model is a multiple of 4 with a non-zero sine part.
pub fn export(c: &Correction) -> Result<TmcExport, ExportError> {
    let i = c.holding_current_a;
    let eps: Vec<(u16, f64)> = c
        .terms
        .iter()
        .filter(|&&(k, a, ph)| k % 4 == 0 && (a * ph.cos() / i).abs() * f64::from(FULL_SCALE) >= 0.25)
        .map(|&(k, a, ph)| (k / 4, a * ph.cos() / i))
        .collect();
    if eps.is_empty() {
        let orders: Vec<String> = c.terms.iter().map(|t| t.0.to_string()).collect();
        return Err(ExportError::NothingFits(format!(
            "a Trinamic table carries only the sine part of orders 4, 8, 12…; this model has orders {} \
             (with no sine part of order 4·j above a quarter count)",
            orders.join(", ")
        )));
    }
    let registers = encode(&quarter_wave(&eps))?;
    let coverage = coverage(c, &registers.decode());
    let wanted: f64 = coverage.iter().map(|o| o.wanted_a.powi(2)).sum();
    let left: f64 = coverage.iter().map(|o| o.residual_a.powi(2)).sum();
    Ok(TmcExport { registers, coverage, power_share: 1.0 - left / wanted.max(1e-300) })
}

/// The q current of a quarter wave as the drive makes it (reference held over each tick,
/// seen from the tick's centre angle), projected on each order of the correction.
pub fn coverage(c: &Correction, q: &[i32; 257]) -> Vec<OrderCoverage> {
    c.terms
        .iter()
        .map(|&(k, amp, ph)| {
            let (s, co) = order_parts(q, k);
            let (s, co) = (s * c.holding_current_a, co * c.holding_current_a);
            // Wanted: amp·sin(kθ + φ) = amp cos φ · sin kθ + amp sin φ · cos kθ.
            let (ws, wc) = (amp * ph.cos(), amp * ph.sin());
            OrderCoverage {
                order: k,
                wanted_a: amp,
                achieved_a: s.hypot(co),
                residual_a: (ws - s).hypot(wc - co),
                expressible: k % 4 == 0,
            }
        })
        .collect()
}

/// The sine and cosine parts of order `k` of the q current the quarter wave `q` makes, per
/// unit of run current: the reference held over each of the 1024 ticks, seen from the tick's
/// centre angle, winding a = `CUR_B`, b = `CUR_A`. For a table of [`quarter_wave`] the sine
/// part of order `4j` is `ε_j` (to the table's rounding).
pub fn order_parts(q: &[i32; 257], k: u16) -> (f64, f64) {
    let scale = 1.0 / f64::from(FULL_SCALE);
    let kf = f64::from(k);
    let (mut s, mut co) = (0.0, 0.0);
    for m in 0..TABLE_TICKS {
        let th = TAU * (m as f64 + 0.5) / 1024.0;
        let (a, b) = (f64::from(wave(q, m + 256)) * scale, f64::from(wave(q, m)) * scale);
        let iq = -a * th.sin() + b * th.cos();
        s += iq * (kf * th).sin();
        co += iq * (kf * th).cos();
    }
    let n = TABLE_TICKS as f64;
    (s * 2.0 / n, co * 2.0 / n)
}

/// The replay table the core runs in `table` mode: winding a = `CUR_B = w(m+256)`, winding
/// b = `CUR_A = w(m)`, the same for both directions.
pub fn table(regs: &TmcRegisters) -> CorrectionTable {
    let q = regs.decode();
    let mut t = CorrectionTable { full_scale: FULL_SCALE, ..Default::default() };
    for m in 0..TABLE_TICKS {
        let e = [wave(&q, m + 256) as i16, wave(&q, m) as i16];
        t.forward[m] = e;
        t.backward[m] = e;
    }
    t
}

/// The part of a profile's detent model a table carries: for orders `4j`, the sine part
/// `A·cos φ` (as amplitude `|A cos φ|`, phase 0 or π); every other order dropped. A
/// controller configured from it with the `angle` law predicts what the table does on the
/// real motor (the uncovered orders still ripple), without the table's integer rounding.
pub fn covered_profile(p: &Profile) -> Result<Profile, ExportError> {
    let name = format!("{} (part a Trinamic table carries)", p.name);
    let detent = p
        .motor
        .detent
        .iter()
        .filter(|h| h.order % 4 == 0)
        .map(|h| {
            let a = h.amplitude_nm * h.phase_rad.cos();
            DetentTerm {
                order: h.order,
                amplitude_nm: a.abs(),
                phase_rad: if a < 0.0 { std::f64::consts::PI } else { 0.0 },
            }
        })
        .collect();
    p.edited(&name, |d| {
        d.name = name.clone();
        d.motor.detent = detent;
    })
    .map_err(|e| ExportError::Invalid(e.to_string()))
}

impl std::fmt::Display for TmcExport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "Trinamic table coverage (share of the model's ripple power the table carries: {:.1} %)",
            100.0 * self.power_share
        )?;
        for o in &self.coverage {
            if o.expressible {
                writeln!(
                    f,
                    "  order {:>2}: wanted {:.4} A, table {:.4} A, left {:.4} A ({:.1} % carried)",
                    o.order,
                    o.wanted_a,
                    o.achieved_a,
                    o.residual_a,
                    100.0 * o.carried_share()
                )?;
            } else {
                writeln!(
                    f,
                    "  order {:>2}: wanted {:.4} A, not expressible in a mirrored quarter wave",
                    o.order, o.wanted_a
                )?;
            }
        }
        Ok(())
    }
}

/// Parses a Klipper TMC section's `driver_MSLUT0` … `driver_START_SIN90` lines (`:` or
/// `=`; comments after `#` or `;`); every register must be present.
pub fn parse_klipper(text: &str, what: &str) -> Result<TmcRegisters, ExportError> {
    let mut v: std::collections::HashMap<String, u64> = std::collections::HashMap::new();
    for (no, line) in text.lines().enumerate() {
        let line = line.split(['#', ';']).next().unwrap_or("").trim();
        let Some((k, val)) = line.split_once([':', '=']) else { continue };
        let k = k.trim();
        if let Some(name) = k.strip_prefix("driver_") {
            let val = val.trim();
            let n: u64 = val.parse().map_err(|_| ExportError::Parse {
                what: format!("{what}:{}", no + 1),
                reason: format!("{} = {val:?}: expected a non-negative integer", crate::escape::line(k)),
            })?;
            v.insert(name.to_uppercase(), n);
        }
    }
    let get = |name: &str, max: u64| -> Result<u64, ExportError> {
        let x = *v.get(name).ok_or_else(|| ExportError::Parse {
            what: what.to_string(),
            reason: format!("driver_{name} is missing"),
        })?;
        if x > max {
            return Err(ExportError::Parse {
                what: what.to_string(),
                reason: format!("driver_{name} = {x}: at most {max}"),
            });
        }
        Ok(x)
    };
    let mut r = TmcRegisters::KLIPPER_DEFAULT;
    for i in 0..8 {
        r.mslut[i] = get(&format!("MSLUT{i}"), u64::from(u32::MAX))? as u32;
    }
    for i in 0..4 {
        r.w[i] = get(&format!("W{i}"), 3)? as u8;
    }
    for i in 0..3 {
        r.x[i] = get(&format!("X{}", i + 1), 255)? as u8;
    }
    r.start_sin = get("START_SIN", 255)? as u8;
    r.start_sin90 = get("START_SIN90", 255)? as u8;
    Ok(r)
}

/// The Klipper config block for a stepper (`axis` such as `tmc5160 stepper_x`, checked by
/// [`klipper_section`]); `name` (the profile's) goes into a comment, escaped to one line.
/// The comments give the share of each order's wanted current the table carries, not a
/// predicted reduction (that is the simulation's to say), and the run current the table was
/// computed for, both ways: Klipper's `run_current` is RMS per phase, the table's scale peak.
pub fn klipper_block(e: &TmcExport, axis: &str, name: &str, current: RunCurrent) -> Result<String, ExportError> {
    let section = klipper_section(axis)?;
    let mut s = format!("# Microstep table from stepdamp (profile \"{}\").\n", crate::escape::line(name));
    s += &format!(
        "# Computed for {current}: set run_current: {:.3} in this section; at another current\n\
         # the table over- or under-corrects (export again with that current).\n",
        current.rms_a()
    );
    for o in &e.coverage {
        s += &format!(
            "#   order {}: {}\n",
            o.order,
            if o.expressible {
                format!("{:.1} % of its compensating current carried", 100.0 * o.carried_share())
            } else {
                "not expressible".into()
            }
        );
    }
    s += &format!("[{section}]\n");
    Ok(s + &e.registers.klipper_lines())
}

#[cfg(test)]
mod tests {
    use super::*;
    use stepdamp_sim::Profile;

    fn patent() -> Correction {
        Correction::from_profile(&Profile::preset("patent-motor").unwrap(), None).unwrap()
    }

    #[test]
    fn klipper_default_registers_decode_to_the_248_sine() {
        let q = TmcRegisters::KLIPPER_DEFAULT.decode();
        for (x, &v) in q.iter().enumerate().skip(1) {
            let want = (248.0 * (TAU * (x as f64 - 0.5) / 1024.0).sin()).round() as i32;
            assert_eq!(v, want, "entry {x}");
        }
        assert_eq!(TmcRegisters::KLIPPER_DEFAULT.mslutsel(), 0xFFFF_8056);
    }

    #[test]
    fn registers_decode_back_to_the_intended_quarter_wave() {
        let e = export(&patent()).unwrap();
        let q = e.registers.decode();
        let eps = 0.02 / 0.3 / 1.9;
        for (x, &v) in q.iter().enumerate() {
            let phi = TAU * x as f64 / 1024.0;
            let want = 248.0 * (phi.sin() + eps / 2.0 * ((3.0 * phi).sin() + (5.0 * phi).sin()));
            assert_eq!(v, want.round() as i32, "entry {x}");
        }
        assert_eq!(i32::from(e.registers.start_sin90), q[256]);
        assert_eq!(e.registers.mslutstart() >> 16, u32::from(e.registers.start_sin90));
        assert_eq!(encode(&q).unwrap(), e.registers);
    }

    #[test]
    fn orders_1_and_2_are_not_expressible_and_order_4_is_covered() {
        let e = export(&patent()).unwrap();
        for o in &e.coverage {
            match o.order {
                4 => assert!(o.expressible && o.reduction_db() > 20.0, "{o:?}"),
                _ => assert!(!o.expressible && o.achieved_a < 0.05 * o.wanted_a, "{o:?}"),
            }
        }
        assert!(e.to_string().contains("not expressible"));
    }

    #[test]
    fn a_model_without_a_fourth_order_sine_part_is_refused() {
        let mut c = patent();
        c.terms.retain(|t| t.0 != 4);
        assert!(matches!(export(&c), Err(ExportError::NothingFits(_))));
        let mut c = patent();
        c.terms = vec![(4, 0.05, std::f64::consts::FRAC_PI_2)];
        assert!(matches!(export(&c), Err(ExportError::NothingFits(_))));
    }

    #[test]
    fn klipper_block_states_its_run_current_as_rms_and_peak() {
        let e = export(&patent()).unwrap();
        let text = klipper_block(&e, "tmc5160 stepper_x", "m", RunCurrent::from_rms(0.65).unwrap()).unwrap();
        assert!(text.contains("0.919 A peak (current vector) = 0.650 A RMS per phase"), "{text}");
        assert!(text.contains("set run_current: 0.650 in this section"), "{text}");
    }

    #[test]
    fn klipper_block_parses_back_to_the_registers() {
        let e = export(&patent()).unwrap();
        let text = klipper_block(&e, "tmc5160 stepper_x", "patent-motor", RunCurrent::from_peak(1.9).unwrap()).unwrap();
        assert!(text.contains("[tmc5160 stepper_x]\ndriver_MSLUT0: "));
        assert_eq!(parse_klipper(&text, "cfg").unwrap(), e.registers);
        let cut: String = text.lines().filter(|l| !l.starts_with("driver_W2")).map(|l| format!("{l}\n")).collect();
        assert!(parse_klipper(&cut, "cfg").unwrap_err().to_string().contains("driver_W2 is missing"));
    }

    proptest::proptest! {
        #[test]
        fn any_encodable_fourth_order_decodes_to_its_quarter_wave(a in 0.002f64..0.06, ph in -3.1f64..3.1) {
            let mut c = patent();
            c.terms = vec![(4, a, ph)];
            match export(&c) {
                Ok(e) => {
                    let q = e.registers.decode();
                    proptest::prop_assert_eq!(encode(&q).unwrap(), e.registers);
                    let eps = a * ph.cos() / c.holding_current_a;
                    for (x, &v) in q.iter().enumerate() {
                        let phi = TAU * x as f64 / 1024.0;
                        let want = 248.0 * (phi.sin() + eps / 2.0 * ((3.0 * phi).sin() + (5.0 * phi).sin()));
                        proptest::prop_assert_eq!(v, want.round() as i32);
                    }
                }
                // Refused only when the sine part is below a quarter count.
                Err(ExportError::NothingFits(_)) => proptest::prop_assert!((a * ph.cos() / c.holding_current_a).abs() * 248.0 < 0.25),
                Err(e) => proptest::prop_assert!(false, "{e}"),
            }
        }
    }

    #[test]
    fn steps_outside_the_widths_are_refused() {
        let mut q = [0i32; 257];
        for (x, v) in q.iter_mut().enumerate() {
            *v = if x % 2 == 0 { 0 } else { 3 };
        }
        assert!(encode(&q).is_err());
        let mut q = [0i32; 257];
        q[1] = 4;
        assert!(encode(&q).is_err());
    }

    #[test]
    fn only_the_sections_klipper_gives_a_wave_table_are_accepted() {
        let e = export(&patent()).unwrap();
        for d in WAVE_TABLE_DRIVERS {
            let axis = format!("{d} stepper_x");
            assert!(
                klipper_block(&e, &axis, "m", RunCurrent::from_peak(1.9).unwrap())
                    .unwrap()
                    .contains(&format!("\n[{axis}]\n"))
            );
        }
        assert!(klipper_block(&e, "tmc5160 manual_stepper belt_1", "m", RunCurrent::from_peak(1.9).unwrap()).is_ok());
        for d in ["tmc2208", "tmc2209", "tmc2660", "tmc2160", "tmc5130", "TMC5160"] {
            let err = klipper_block(&e, &format!("{d} stepper_x"), "m", RunCurrent::from_peak(1.9).unwrap())
                .unwrap_err()
                .to_string();
            assert!(err.contains("tmc2130, tmc2240, tmc5160") && err.contains(d), "{err}");
        }
        for bad in ["tmc5160", "tmc5160 stepper_x]\n[gcode_macro X]", "tmc5160  stepper_x", "tmc5160 a\x1b"] {
            let err = klipper_block(&e, bad, "m", RunCurrent::from_peak(1.9).unwrap()).unwrap_err().to_string();
            assert!(!err.chars().any(crate::escape::is_unsafe), "{err:?}");
        }
    }

    #[test]
    fn a_hostile_profile_name_stays_inside_its_comment() {
        let e = export(&patent()).unwrap();
        let text = klipper_block(
            &e,
            "tmc5160 stepper_x",
            "m\n[gcode_macro PWNED]\ngcode: M112\x1b",
            RunCurrent::from_peak(1.9).unwrap(),
        )
        .unwrap();
        // Every line is a comment, the one section header, or a driver option.
        for l in text.lines() {
            assert!(
                l.starts_with('#') || l == "[tmc5160 stepper_x]" || l.starts_with("driver_"),
                "live line {l:?} in\n{text}"
            );
        }
        assert!(!text.contains('\x1b'));
        assert_eq!(parse_klipper(&text, "cfg").unwrap(), e.registers);
    }

    #[test]
    fn replay_table_origin_is_coil_b_on_winding_a() {
        let t = table(&TmcRegisters::KLIPPER_DEFAULT);
        // MSCNT 0: CUR_A = START_SIN = 0 on winding b, CUR_B = Q[256] on winding a.
        assert_eq!(t.forward[0], [248, 0]);
        assert_eq!(t.forward[256][1], 248);
        assert_eq!(t.forward[512][0], -248);
    }

    #[test]
    fn a_key_with_control_bytes_is_quoted_escaped() {
        // Found by fuzzing: the key went raw into the message (the value was escaped).
        let e = parse_klipper("driver_MSLUT0\u{0}\u{1b}[2J = x\n", "t.cfg").unwrap_err().to_string();
        assert!(!e.chars().any(char::is_control), "{e:?}");
        assert!(e.contains("t.cfg:1") && e.contains("driver_MSLUT0"), "{e}");
    }
}
