//! Prusa-Firmware-Buddy phase stepping (verified against its source; see
//! `docs/exporters.md` for the files and commit).
//!
//! The firmware keeps, per axis and direction, a spectrum of 17 items `{mag, pha}` (f32,
//! n = 0…16) and turns it into a phase shift per tick of its 1024-tick electrical period:
//! `shift[i] = round(4096/(2π) · Σ_n mag_n sin(n·2πi/1024 + pha_n))` stored as `int8_t`
//! (units of 2π/4096 rad); the coil currents of tick `i` are then
//! `a = sin_lut(4i + shift[i])`, `b = cos_lut(4i + shift[i])` on a 4096-per-period sine
//! table of amplitude 248. So `Δ = Σ mag sin(nθ + pha)` rotates the current vector in the
//! direction of increasing phase at constant magnitude. With stepdamp's winding a on
//! Prusa's `b` (cosine) coil and winding b on `a` (sine), `θe = 2π·phase/1024` and the
//! patent's injection is `mag_k = A_k/(Km·I)`, `pha_k = φ_k` (first order in `Δ`).
//!
//! The forward table is used while the physical speed is > 0 (phase increasing).

use crate::{Correction, ExportError};
use stepdamp_core::{CorrectionTable, TABLE_TICKS};
use stepdamp_sim::Profile;
use stepdamp_sim::profile::DetentTerm;

/// Items in a Prusa spectrum (`CORRECTION_HARMONICS + 1`).
pub const ITEMS: usize = 17;
/// Bytes of a correction file: 32 zero bytes, then 17 × {f32 mag, f32 pha} little-endian.
pub const FILE_BYTES: usize = 32 + ITEMS * 8;
/// Amplitude of the firmware's sine table (`CURRENT_AMPLITUDE`).
pub const CURRENT_AMPLITUDE: i16 = 248;
/// Phase units per electrical period (`SIN_PERIOD`): the shift's resolution is 2π/4096.
pub const SIN_PERIOD: i32 = 4096;

/// One direction's spectrum: `Δ(θ) = Σ_n mag[n] sin(n θ + pha[n])`, rad.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spectrum {
    /// Magnitudes, rad.
    pub mag: [f32; ITEMS],
    /// Phases, rad.
    pub pha: [f32; ITEMS],
}

/// Both directions of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PrusaCorrection {
    /// Used while the phase increases.
    pub forward: Spectrum,
    /// Used while the phase decreases.
    pub backward: Spectrum,
}

impl Spectrum {
    /// The spectrum of a correction: `mag_k = c_k/I`, `pha_k = φ_k`. Orders above 16 are
    /// refused (Prusa has no place for them); a shift beyond the firmware's `int8_t`
    /// (±127·2π/4096 = ±0.195 rad) is refused too.
    pub fn from_correction(c: &Correction) -> Result<Self, ExportError> {
        let mut s = Spectrum::default();
        for &(k, amp, ph) in &c.terms {
            let n = usize::from(k);
            if n >= ITEMS {
                return Err(ExportError::Invalid(format!(
                    "detent order {k}: Prusa's correction holds orders 0..=16 only"
                )));
            }
            s.mag[n] = (amp / c.holding_current_a) as f32;
            s.pha[n] = ph as f32;
        }
        let worst = s.shifts_unwrapped().iter().map(|v| v.abs()).max().unwrap_or(0);
        if worst > 127 {
            return Err(ExportError::Invalid(format!(
                "the correction reaches {:.3} rad, beyond the ±{:.3} rad Prusa's int8 phase shift holds: raise --current",
                worst as f64 * std::f64::consts::TAU / f64::from(SIN_PERIOD),
                127.0 * std::f64::consts::TAU / f64::from(SIN_PERIOD)
            )));
        }
        Ok(s)
    }

    /// `round(4096/2π · Δ(2πi/1024))` per tick, before the firmware's `int8_t` store.
    fn shifts_unwrapped(&self) -> Vec<i32> {
        (0..TABLE_TICKS)
            .map(|i| {
                let th = i as f32 * std::f32::consts::TAU / TABLE_TICKS as f32;
                let d: f32 = (0..ITEMS).map(|n| self.mag[n] * (n as f32 * th + self.pha[n]).sin()).sum();
                (SIN_PERIOD as f32 / std::f32::consts::TAU * d).round() as i32
            })
            .collect()
    }

    /// The firmware's phase shift per tick, in 2π/4096 rad, as stored (`int8_t`, wrapping).
    pub fn shifts(&self) -> Vec<i8> {
        self.shifts_unwrapped().into_iter().map(|v| v as i8).collect()
    }

    /// The coil currents the firmware sets per tick, as stepdamp windings `[a, b]`:
    /// `[cos_lut(4i + shift), sin_lut(4i + shift)]`, full scale 248.
    pub fn currents(&self) -> Vec<[i16; 2]> {
        self.shifts()
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                let pha = 4 * i as i32 + i32::from(s);
                [sin_lut(pha + SIN_PERIOD / 4), sin_lut(pha)]
            })
            .collect()
    }
}

/// The firmware's sine table: a quarter of `(u8)(248·sin(π/2·i/1024) + 0.5)`, mirrored.
pub fn sin_lut(x: i32) -> i16 {
    let q = SIN_PERIOD / 4;
    let quarter = |i: i32| {
        (f32::from(CURRENT_AMPLITUDE) * (std::f32::consts::FRAC_PI_2 * i as f32 / q as f32).sin() + 0.5) as i16
    };
    let x = x.rem_euclid(SIN_PERIOD);
    if x <= q {
        quarter(x)
    } else if x <= 2 * q {
        quarter(2 * q - x)
    } else if x <= 3 * q {
        -quarter(x - 2 * q)
    } else {
        -quarter(SIN_PERIOD - x)
    }
}

impl PrusaCorrection {
    /// The same spectrum for both directions (a detent model does not depend on it).
    pub fn from_correction(c: &Correction) -> Result<Self, ExportError> {
        let s = Spectrum::from_correction(c)?;
        Ok(PrusaCorrection { forward: s, backward: s })
    }

    /// `M973` lines for `axis` (`X` or `Y`): `M973 XF<mag>,<pha> <mag>,<pha> …` then `XB`.
    /// Values print in the shortest form that reads back to the same `f32`.
    pub fn m973(&self, axis: char) -> String {
        let line = |dir: char, s: &Spectrum| {
            let pairs: Vec<String> = (0..ITEMS).map(|n| format!("{},{}", s.mag[n], s.pha[n])).collect();
            format!("M973 {axis}{dir}{}\n", pairs.join(" "))
        };
        line('F', &self.forward) + &line('B', &self.backward)
    }

    /// The replay table the core runs in `table` mode.
    pub fn table(&self) -> CorrectionTable {
        let mut t = CorrectionTable { full_scale: CURRENT_AMPLITUDE, ..Default::default() };
        for (i, e) in self.forward.currents().into_iter().enumerate() {
            t.forward[i] = e;
        }
        for (i, e) in self.backward.currents().into_iter().enumerate() {
            t.backward[i] = e;
        }
        t
    }
}

/// A correction file (`/internal/phase_step_<axis>_fwd|bck`): 32 zero bytes, then 17 ×
/// {f32 mag, f32 pha} little-endian (the firmware's `CorrectionSaveFormat` on a
/// little-endian Cortex-M).
pub fn encode_file(s: &Spectrum) -> Vec<u8> {
    let mut out = vec![0u8; 32];
    for n in 0..ITEMS {
        out.extend_from_slice(&s.mag[n].to_le_bytes());
        out.extend_from_slice(&s.pha[n].to_le_bytes());
    }
    out
}

/// Reads a correction file. The firmware loads only a file of at least 168 bytes (it reads
/// exactly 168); the 32 reserved bytes must be zero, and every value finite.
pub fn decode_file(bytes: &[u8], what: &str) -> Result<Spectrum, ExportError> {
    let bad = |reason: String| ExportError::Parse { what: what.to_string(), reason };
    if bytes.len() != FILE_BYTES {
        return Err(bad(format!("{} bytes: a Prusa correction file has exactly {FILE_BYTES}", bytes.len())));
    }
    if bytes[..32].iter().any(|&b| b != 0) {
        return Err(bad("the 32-byte header is not all zero (an unknown version)".into()));
    }
    let mut s = Spectrum::default();
    for n in 0..ITEMS {
        let at = 32 + 8 * n;
        let f = |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
        s.mag[n] = f(at);
        s.pha[n] = f(at + 4);
        if !(s.mag[n].is_finite() && s.pha[n].is_finite()) {
            return Err(bad(format!("item {n} is not finite")));
        }
    }
    Ok(s)
}

/// Parses `M972` output: lines `<axis>, <F|B>, <n>, <mag>, <pha>` (other lines, such as
/// `ok`, are skipped). `axis` picks one axis when the output has several; all 17 items of
/// both directions must be present.
pub fn parse_m972(text: &str, axis: Option<char>, what: &str) -> Result<PrusaCorrection, ExportError> {
    let bad = |line: usize, reason: String| ExportError::Parse { what: format!("{what}:{line}"), reason };
    let mut out = PrusaCorrection::default();
    let mut seen = [[false; ITEMS]; 2];
    let mut axis_seen: Option<char> = axis;
    for (no, line) in text.lines().enumerate() {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 5 || f[0].len() != 1 || !matches!(f[1], "F" | "B") {
            continue;
        }
        let ax = f[0].chars().next().unwrap_or(' ');
        match axis_seen {
            None => axis_seen = Some(ax),
            Some(a) if a != ax => {
                if axis.is_none() {
                    return Err(bad(no + 1, format!("axes {a} and {ax} both present: choose one with --axis")));
                }
                continue;
            }
            _ => {}
        }
        let n: usize = f[2].parse().map_err(|_| bad(no + 1, format!("index {:?} is not a number", f[2])))?;
        if n >= ITEMS {
            return Err(bad(no + 1, format!("index {n}: must be in 0..=16")));
        }
        let num = |s: &str| -> Result<f32, ExportError> {
            s.parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(no + 1, format!("{s:?} is not a finite number")))
        };
        let (d, spec) = if f[1] == "F" { (0, &mut out.forward) } else { (1, &mut out.backward) };
        spec.mag[n] = num(f[3])?;
        spec.pha[n] = num(f[4])?;
        seen[d][n] = true;
    }
    for (d, name) in [(0, "F"), (1, "B")] {
        if let Some(n) = seen[d].iter().position(|s| !s) {
            return Err(ExportError::Parse {
                what: what.to_string(),
                reason: format!("direction {name} item {n} is missing (M972 prints 17 items per direction)"),
            });
        }
    }
    Ok(out)
}

/// The M972 text of a correction (what the firmware prints, 5 decimals), for tests and docs.
pub fn m972_text(c: &PrusaCorrection, axis: char) -> String {
    let mut t = String::new();
    for (dir, s) in [('F', &c.forward), ('B', &c.backward)] {
        for n in 0..ITEMS {
            t += &format!("{axis}, {dir}, {n}, {:.5}, {:.5}\n", s.mag[n], s.pha[n]);
        }
    }
    t
}

/// A detent model equivalent to a spectrum (the inverse of [`Spectrum::from_correction`]):
/// `(order, A_k = mag_k·Km·I in N·m, φ_k)` for n = 1..16 with a non-zero magnitude. A
/// negative magnitude becomes a positive amplitude with the phase turned by π. Item 0 (a
/// constant shift) is not a detent torque and is returned separately, rad.
pub fn to_detent(s: &Spectrum, km_nm_per_a: f64, current_a: f64) -> (Vec<(u16, f64, f64)>, f64) {
    let mut terms = Vec::new();
    for n in 1..ITEMS {
        let (m, p) = (f64::from(s.mag[n]), f64::from(s.pha[n]));
        if m == 0.0 {
            continue;
        }
        let (a, ph) = if m < 0.0 { (-m, p + std::f64::consts::PI) } else { (m, p) };
        let ph = (ph + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        terms.push((n as u16, a * km_nm_per_a * current_a, ph));
    }
    (terms, f64::from(s.mag[0]) * f64::from(s.pha[0]).sin())
}

/// Parses `M973 <axis><F|B><mag>,<pha> …` lines (as the firmware's `parse_pairs` reads
/// them: pairs separated by one space; missing items are zero). Both directions must be
/// given; `axis` picks one when several are present.
pub fn parse_m973(text: &str, axis: Option<char>, what: &str) -> Result<PrusaCorrection, ExportError> {
    let mut out = PrusaCorrection::default();
    let mut seen = [false; 2];
    let mut axis_seen = axis;
    for (no, line) in text.lines().enumerate() {
        let Some(rest) = line.trim().strip_prefix("M973 ") else { continue };
        let bad = |reason: String| ExportError::Parse { what: format!("{what}:{}", no + 1), reason };
        let mut chars = rest.chars();
        let (ax, dir) = (chars.next().unwrap_or(' '), chars.next().unwrap_or(' '));
        if !matches!(ax, 'X' | 'Y') || !matches!(dir, 'F' | 'B') {
            return Err(bad(format!("{rest:?}: expected <X|Y><F|B> then mag,pha pairs")));
        }
        match axis_seen {
            None => axis_seen = Some(ax),
            Some(a) if a != ax => {
                if axis.is_none() {
                    return Err(bad(format!("axes {a} and {ax} both present: choose one with --axis")));
                }
                continue;
            }
            _ => {}
        }
        let mut s = Spectrum::default();
        let pairs: Vec<&str> = chars.as_str().trim().split(' ').filter(|p| !p.is_empty()).collect();
        if pairs.len() > ITEMS {
            return Err(bad(format!("{} pairs: at most {ITEMS}", pairs.len())));
        }
        for (n, p) in pairs.iter().enumerate() {
            let (m, ph) = p.split_once(',').ok_or_else(|| bad(format!("{p:?}: expected mag,pha")))?;
            let num = |v: &str| {
                v.parse::<f32>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad(format!("{v:?} is not a finite number")))
            };
            s.mag[n] = num(m)?;
            s.pha[n] = num(ph)?;
        }
        let d = usize::from(dir == 'B');
        seen[d] = true;
        if d == 0 {
            out.forward = s;
        } else {
            out.backward = s;
        }
    }
    if let Some(d) = seen.iter().position(|s| !s) {
        return Err(ExportError::Parse {
            what: what.to_string(),
            reason: format!("no M973 line for direction {}", if d == 0 { 'F' } else { 'B' }),
        });
    }
    Ok(out)
}

/// A profile equal to `base` with the detent model a Prusa correction stands for, at
/// holding current `current_a`: each order's phasor `mag·e^{i·pha}` averaged over the two
/// directions (a detent torque does not depend on the direction; what differs between
/// the directions is returned as the largest phasor difference, rad, for the user to see).
pub fn import_profile(base: &Profile, c: &PrusaCorrection, current_a: f64) -> Result<(Profile, f64), ExportError> {
    if !(current_a.is_finite() && current_a > 0.0) {
        return Err(ExportError::Invalid(format!("--current {current_a} A: must be finite and > 0")));
    }
    let mut avg = Spectrum::default();
    let mut spread: f64 = 0.0;
    for n in 0..ITEMS {
        let (f, b) = (&c.forward, &c.backward);
        let (fx, fy) =
            (f64::from(f.mag[n]) * f64::from(f.pha[n]).cos(), f64::from(f.mag[n]) * f64::from(f.pha[n]).sin());
        let (bx, by) =
            (f64::from(b.mag[n]) * f64::from(b.pha[n]).cos(), f64::from(b.mag[n]) * f64::from(b.pha[n]).sin());
        spread = spread.max((fx - bx).hypot(fy - by));
        let (x, y) = ((fx + bx) / 2.0, (fy + by) / 2.0);
        avg.mag[n] = x.hypot(y) as f32;
        avg.pha[n] = y.atan2(x) as f32;
    }
    let (terms, _) = to_detent(&avg, base.motor.km_nm_per_a, current_a);
    let name = stepdamp_sim::profile::name::derived_name(&base.name, " (Prusa correction)");
    let p = base
        .edited(&name, |d| {
            d.name = name.clone();
            d.motor.detent = terms
                .into_iter()
                .map(|(order, amplitude_nm, phase_rad)| DetentTerm { order, amplitude_nm, phase_rad })
                .collect();
            d.drive.holding_current_a = current_a.min(d.drive.current_limit_a);
        })
        .map_err(|e| ExportError::Invalid(e.to_string()))?;
    Ok((p, spread))
}

#[cfg(test)]
mod tests {
    use super::*;
    use stepdamp_sim::Profile;

    fn patent() -> Correction {
        Correction::from_profile(&Profile::preset("patent-motor").unwrap(), None).unwrap()
    }

    #[test]
    fn patent_spectrum_is_a_over_km_i_at_the_profiles_phase() {
        let s = Spectrum::from_correction(&patent()).unwrap();
        assert!((f64::from(s.mag[4]) - 0.02 / (0.3 * 1.9)).abs() < 1e-7);
        assert!((f64::from(s.pha[2]) - 0.7).abs() < 1e-7);
        assert_eq!(s.mag[0], 0.0);
        assert_eq!(s.mag[3], 0.0);
    }

    #[test]
    fn files_round_trip_byte_for_byte() {
        let s = Spectrum::from_correction(&patent()).unwrap();
        let bytes = encode_file(&s);
        assert_eq!(bytes.len(), 168);
        assert!(bytes[..32].iter().all(|&b| b == 0));
        // Item 4's magnitude sits at 32 + 4·8, little-endian.
        assert_eq!(&bytes[64..68], &s.mag[4].to_le_bytes());
        let back = decode_file(&bytes, "t").unwrap();
        assert_eq!(back, s);
        assert_eq!(encode_file(&back), bytes);
        assert!(decode_file(&bytes[..167], "t").is_err());
        let mut v = bytes.clone();
        v[3] = 1;
        assert!(decode_file(&v, "t").is_err());
    }

    #[test]
    fn m973_values_read_back_exactly_and_m972_parses() {
        let c = PrusaCorrection::from_correction(&patent()).unwrap();
        let text = c.m973('X');
        let mut lines = text.lines();
        let f = lines.next().unwrap();
        assert!(f.starts_with("M973 XF"));
        assert!(lines.next().unwrap().starts_with("M973 XB"));
        // What the firmware's parse_pairs does: split on ' ', then on ','.
        let pairs: Vec<(f32, f32)> = f["M973 XF".len()..]
            .split(' ')
            .map(|p| {
                let (a, b) = p.split_once(',').unwrap();
                (a.parse().unwrap(), b.parse().unwrap())
            })
            .collect();
        assert_eq!(pairs.len(), 17);
        for (n, pair) in pairs.iter().enumerate() {
            assert_eq!(*pair, (c.forward.mag[n], c.forward.pha[n]));
        }
        let back = parse_m972(&format!("ok\n{}ok\n", m972_text(&c, 'X')), None, "m972").unwrap();
        for n in 0..ITEMS {
            assert!((back.forward.mag[n] - c.forward.mag[n]).abs() <= 5e-6);
            assert!((back.backward.pha[n] - c.backward.pha[n]).abs() <= 5e-6);
        }
        let missing: String = m972_text(&c, 'X').lines().skip(1).map(|l| format!("{l}\n")).collect();
        assert!(parse_m972(&missing, None, "m").unwrap_err().to_string().contains("item 0 is missing"));
    }

    #[test]
    fn angle_origin_and_direction_a_zero_correction_is_plain_microstepping() {
        // Tick 0: stepdamp's winding a (Prusa's cosine coil) at full current, b at zero —
        // θe = 0, the d axis on winding a. Tick 256 (a quarter period): b at full.
        let t = PrusaCorrection::default().table();
        assert_eq!(t.forward[0], [248, 0]);
        assert_eq!(t.forward[256], [0, 248]);
        assert_eq!(t.forward[512], [-248, 0]);
    }

    #[test]
    fn a_positive_shift_turns_the_current_vector_towards_positive_theta() {
        // mag_0 with pha_0 = π/2 is a constant Δ: the current vector leads θe by Δ, so the
        // q current (−i_a sin θe + i_b cos θe) is +I·sin Δ, the patent's +i_q.
        let mut s = Spectrum::default();
        s.mag[0] = 0.05;
        s.pha[0] = std::f32::consts::FRAC_PI_2;
        let cur = s.currents();
        for &i in &[0usize, 100, 300, 700] {
            let th = std::f64::consts::TAU * i as f64 / 1024.0;
            let [a, b] = cur[i];
            let q = -f64::from(a) * th.sin() + f64::from(b) * th.cos();
            assert!((q / 248.0 - 0.05f64.sin()).abs() < 0.01, "{i}: {q}");
        }
    }

    #[test]
    fn shifts_follow_the_firmware_formula_and_too_large_is_refused() {
        let s = Spectrum::from_correction(&patent()).unwrap();
        let sh = s.shifts();
        let c = patent();
        for i in [0usize, 17, 500, 1000] {
            let th = std::f64::consts::TAU * i as f64 / 1024.0;
            let want = (4096.0 / std::f64::consts::TAU * c.delta_rad(th)).round();
            assert!((f64::from(sh[i]) - want).abs() <= 1.0, "{i}");
        }
        let mut big = patent();
        big.holding_current_a = 0.1;
        assert!(Spectrum::from_correction(&big).unwrap_err().to_string().contains("int8"));
    }

    #[test]
    fn m973_lines_parse_back_and_import_gives_the_profile_again() {
        let c = PrusaCorrection::from_correction(&patent()).unwrap();
        let back = parse_m973(&c.m973('X'), None, "g").unwrap();
        assert_eq!(back, c);
        let base = Profile::preset("patent-motor").unwrap();
        let (p, spread) = import_profile(&base, &back, 1.9).unwrap();
        assert_eq!(spread, 0.0);
        for h in &base.motor.detent {
            let g = p.motor.detent.iter().find(|g| g.order == h.order).unwrap();
            assert!((g.amplitude_nm - h.amplitude_nm).abs() < 1e-7 && (g.phase_rad - h.phase_rad).abs() < 1e-6);
        }
        assert!(parse_m973("M973 XF0.1,0.2\n", None, "g").unwrap_err().to_string().contains("direction B"));
    }

    proptest::proptest! {
        #[test]
        fn any_finite_spectrum_round_trips_through_file_and_m973(
            mag in proptest::collection::vec(-1.0f32..1.0, ITEMS),
            pha in proptest::collection::vec(-4.0f32..4.0, ITEMS),
        ) {
            let mut s = Spectrum::default();
            s.mag.copy_from_slice(&mag);
            s.pha.copy_from_slice(&pha);
            let bytes = encode_file(&s);
            proptest::prop_assert_eq!(encode_file(&decode_file(&bytes, "t").unwrap()), bytes);
            let c = PrusaCorrection { forward: s, backward: s };
            proptest::prop_assert_eq!(parse_m973(&c.m973('Y'), None, "g").unwrap(), c);
        }
    }

    #[test]
    fn import_inverts_export() {
        let c = patent();
        let s = Spectrum::from_correction(&c).unwrap();
        let (terms, offset) = to_detent(&s, 0.3, 1.9);
        assert_eq!(offset, 0.0);
        assert_eq!(terms.len(), 3);
        for (k, a, ph) in terms {
            let h =
                Profile::preset("patent-motor").unwrap().motor.detent.iter().copied().find(|h| h.order == k).unwrap();
            assert!((a - h.amplitude_nm).abs() < 1e-7 && (ph - h.phase_rad).abs() < 1e-6, "{k}");
        }
    }
}
