//! Power-stage modulators: the patent's three-leg common-leg stage (eqs. 10–13) and two
//! H-bridges. Both turn requested phase voltages `(v_a, v_b)` into leg duties in `[0, 1]`,
//! scaling the voltage vector down (direction kept) when the bus cannot make it.
//!
//! **Three legs** α, β, γ, winding A between α and γ, winding B between β and γ. With
//! `v_max = max(v_a, v_b, 0)`, `v_min = min(v_a, v_b, 0)`, `v_o = Vdc/2 − (v_max+v_min)/2`,
//! legs `v_α = v_a + v_o`, `v_β = v_b + v_o`, `v_γ = v_o`. The demand fits the bus iff
//! `v_max − v_min ≤ Vdc` (a hexagon in the `(v_a, v_b)` plane, inscribed circle radius
//! `Vdc/√2`, vertices at `Vdc` on the axes and on the diagonal `v_a = v_b`).
//!
//! **Two H-bridges**: legs A+, A−, B+, B−, `d = ½ ± v/(2 Vdc)`; the demand fits iff
//! `|v_a|, |v_b| ≤ Vdc`.
//!
//! Cost: a handful of compares, one division when limiting (the inverse of `Vdc` can be
//! precomputed: [`Topology::modulate_with_inverse`]). Duties are exact to a few ulp;
//! they are always finite and in `[0, 1]`, whatever the input (non-finite demands give
//! zero volts).

use crate::park::Ab;

/// Power stage topology.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Topology {
    /// The patent's three-leg stage with a shared (common) leg γ (6 switches).
    #[default]
    ThreeLeg,
    /// One full H-bridge per phase (8 switches).
    TwoHBridge,
}

/// Leg duties in `[0, 1]`: three-leg `[α, β, γ, 0]`; two H-bridges `[A+, A−, B+, B−]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LegDuties(pub [f32; 4]);

/// The result of modulation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Modulated {
    /// Leg duties.
    pub duties: LegDuties,
    /// Factor in `[0, 1]` applied to the requested vector (1 when it fitted the bus).
    pub scale: f32,
}

impl Topology {
    /// Number of legs used in [`LegDuties`].
    pub const fn legs(self) -> usize {
        match self {
            Topology::ThreeLeg => 3,
            Topology::TwoHBridge => 4,
        }
    }

    /// The largest `|v|` in any direction that always fits: `Vdc/√2` (three legs) or
    /// `Vdc` (H-bridges), as a fraction of `Vdc`.
    pub const fn inscribed_radius_per_vdc(self) -> f32 {
        match self {
            Topology::ThreeLeg => core::f32::consts::FRAC_1_SQRT_2,
            Topology::TwoHBridge => 1.0,
        }
    }

    /// Turns requested winding voltages (V) into leg duties for bus voltage `vdc` (V > 0).
    #[inline]
    pub fn modulate(self, v: Ab, vdc: f32) -> Modulated {
        self.modulate_with_inverse(v, vdc, 1.0 / vdc)
    }

    /// [`Topology::modulate`] with `inv_vdc = 1/vdc` precomputed (saves a division per
    /// period when the bus voltage is fixed). A non-finite or non-positive `vdc` or a
    /// non-finite `inv_vdc` gives zero volts.
    #[inline]
    pub fn modulate_with_inverse(self, v: Ab, vdc: f32, inv_vdc: f32) -> Modulated {
        if !(v.a.is_finite() && v.b.is_finite() && vdc.is_finite() && vdc > 0.0 && inv_vdc.is_finite()) {
            return Modulated { duties: self.neutral(), scale: 0.0 };
        }
        let inv = inv_vdc;
        match self {
            Topology::ThreeLeg => {
                // v is finite here: compare-and-select, no fmaxf/fminf calls.
                let vmax = crate::at_least(crate::at_least(v.a, v.b), 0.0);
                let vmin = crate::at_most(crate::at_most(v.a, v.b), 0.0);
                let span = vmax - vmin;
                let scale = if span > vdc { vdc / span } else { 1.0 };
                let (va, vb) = (v.a * scale, v.b * scale);
                let vo = 0.5 * vdc - 0.5 * (vmax + vmin) * scale;
                let d = [clamp01((va + vo) * inv), clamp01((vb + vo) * inv), clamp01(vo * inv), 0.0];
                Modulated { duties: LegDuties(d), scale }
            }
            Topology::TwoHBridge => {
                let m = crate::at_least(v.a.abs(), v.b.abs());
                let scale = if m > vdc { vdc / m } else { 1.0 };
                let ha = 0.5 * v.a * scale * inv;
                let hb = 0.5 * v.b * scale * inv;
                let d = [clamp01(0.5 + ha), clamp01(0.5 - ha), clamp01(0.5 + hb), clamp01(0.5 - hb)];
                Modulated { duties: LegDuties(d), scale }
            }
        }
    }

    /// Duties that put zero volts on both windings.
    pub const fn neutral(self) -> LegDuties {
        match self {
            Topology::ThreeLeg => LegDuties([0.5, 0.5, 0.5, 0.0]),
            Topology::TwoHBridge => LegDuties([0.5; 4]),
        }
    }

    /// The average winding voltages, as fractions of `Vdc`, that leg duties make
    /// (what the power stage applies; used by the simulator and the tests).
    #[inline]
    pub fn winding_voltages_per_vdc(self, d: &LegDuties) -> (f32, f32) {
        match self {
            Topology::ThreeLeg => (d.0[0] - d.0[2], d.0[1] - d.0[2]),
            Topology::TwoHBridge => (d.0[0] - d.0[1], d.0[2] - d.0[3]),
        }
    }
}

#[inline]
fn clamp01(x: f32) -> f32 {
    crate::bound(x, 0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const TOPOLOGIES: [Topology; 2] = [Topology::ThreeLeg, Topology::TwoHBridge];

    /// The bus voltage a demand needs (it fits iff this is ≤ `Vdc`): the span of the three
    /// legs `max(v_a, v_b, 0) − min(v_a, v_b, 0)`, or the larger winding voltage for
    /// H-bridges. Written from the module docs, not from the code under test.
    fn fit_measure(t: Topology, va: f32, vb: f32) -> f32 {
        match t {
            Topology::ThreeLeg => {
                let hi = if va > vb { va } else { vb };
                let lo = if va < vb { va } else { vb };
                (if hi > 0.0 { hi } else { 0.0 }) - (if lo < 0.0 { lo } else { 0.0 })
            }
            Topology::TwoHBridge => {
                if va.abs() > vb.abs() {
                    va.abs()
                } else {
                    vb.abs()
                }
            }
        }
    }

    #[test]
    fn precomputed_inverse_gives_the_same_duties() {
        for t in TOPOLOGIES {
            for v in [Ab { a: 10.0, b: -4.0 }, Ab { a: 40.0, b: -20.0 }, Ab { a: -3.3, b: 7.1 }] {
                assert_eq!(t.modulate(v, 48.0), t.modulate_with_inverse(v, 48.0, 1.0 / 48.0));
            }
            assert_eq!(t.modulate_with_inverse(Ab { a: 1.0, b: 1.0 }, 48.0, f32::INFINITY).duties, t.neutral());
        }
    }

    #[test]
    fn three_leg_matches_patent_equations_10_to_13() {
        // v_a = 10, v_b = −4, Vdc = 48: v_max = 10, v_min = −4, v_o = 24 − 3 = 21.
        let m = Topology::ThreeLeg.modulate(Ab { a: 10.0, b: -4.0 }, 48.0);
        let want = [31.0 / 48.0, 17.0 / 48.0, 21.0 / 48.0];
        for (d, w) in m.duties.0.iter().zip(want) {
            assert!((d - w).abs() < 1e-6);
        }
        assert_eq!(m.scale, 1.0);
    }

    #[test]
    fn three_leg_limits_along_the_hexagon_keeping_direction() {
        // Opposite signs: span = |v_a| + |v_b| = 60 > 48 → scale 0.8.
        let m = Topology::ThreeLeg.modulate(Ab { a: 40.0, b: -20.0 }, 48.0);
        assert!((m.scale - 0.8).abs() < 1e-6);
        let (a, b) = Topology::ThreeLeg.winding_voltages_per_vdc(&m.duties);
        assert!((a * 48.0 - 32.0).abs() < 1e-4 && (b * 48.0 + 16.0).abs() < 1e-4);
        // Same signs: the diagonal reaches Vdc on both windings.
        let m = Topology::ThreeLeg.modulate(Ab { a: 48.0, b: 48.0 }, 48.0);
        assert_eq!(m.scale, 1.0);
    }

    #[test]
    fn non_finite_demand_gives_zero_volts() {
        for t in TOPOLOGIES {
            for v in [Ab { a: f32::NAN, b: 1.0 }, Ab { a: 1.0, b: f32::INFINITY }] {
                let m = t.modulate(v, 48.0);
                assert_eq!(t.winding_voltages_per_vdc(&m.duties), (0.0, 0.0));
            }
            let m = t.modulate(Ab { a: 1.0, b: 1.0 }, f32::NAN);
            assert_eq!(m.duties, t.neutral());
        }
    }

    proptest! {
        #[test]
        fn duties_always_lie_in_zero_to_one(
            a in proptest::num::f32::ANY, b in proptest::num::f32::ANY,
            vdc in proptest::num::f32::ANY
        ) {
            for t in TOPOLOGIES {
                let m = t.modulate(Ab { a, b }, vdc);
                for d in m.duties.0 {
                    prop_assert!((0.0..=1.0).contains(&d), "{t:?} {a} {b} {vdc} -> {d}");
                }
            }
        }

        #[test]
        fn demands_are_reproduced_exactly_iff_they_fit_the_bus(
            ua in -2.5f32..2.5, ub in -2.5f32..2.5, vdc in 1.0f32..400.0
        ) {
            // A wide box around the feasible region (hexagon or square of "radius" Vdc), so
            // both fitting and non-fitting demands, near the boundary and far out, are drawn.
            let v = Ab { a: ua * vdc, b: ub * vdc };
            for t in TOPOLOGIES {
                let m = t.modulate(v, vdc);
                for d in m.duties.0 {
                    prop_assert!((0.0..=1.0).contains(&d), "{t:?} {v:?} {vdc} -> {d}");
                }
                let (a, b) = t.winding_voltages_per_vdc(&m.duties);
                let (a, b) = (a * vdc, b * vdc);
                let tol = 1e-5 * vdc;
                if fit_measure(t, v.a, v.b) <= vdc {
                    prop_assert_eq!(m.scale, 1.0, "{:?} {:?} fits {}", t, v, vdc);
                    prop_assert!((a - v.a).abs() <= tol && (b - v.b).abs() <= tol,
                        "{t:?} {v:?} {vdc}: made ({a}, {b})");
                } else {
                    prop_assert!(m.scale < 1.0, "{:?} {:?} does not fit {}", t, v, vdc);
                    // What the legs make is the demand scaled onto the boundary: not inside
                    // it (over-limited) and not beyond it (clipped duties).
                    prop_assert!((a - v.a * m.scale).abs() <= tol && (b - v.b * m.scale).abs() <= tol,
                        "{t:?} {v:?} {vdc}: made ({a}, {b}), scale {}", m.scale);
                    let f = fit_measure(t, a, b);
                    prop_assert!((f - vdc).abs() <= tol, "{t:?} {v:?} {vdc}: boundary measure {f}");
                }
            }
        }

        #[test]
        fn demands_beyond_the_bus_keep_their_direction(
            a in -1000.0f32..1000.0, b in -1000.0f32..1000.0, vdc in 1.0f32..100.0
        ) {
            for t in TOPOLOGIES {
                let m = t.modulate(Ab { a, b }, vdc);
                let (x, y) = t.winding_voltages_per_vdc(&m.duties);
                let (x, y) = (x * vdc, y * vdc);
                // Same direction: cross product ~ 0, dot product ≥ 0, scaled by m.scale.
                prop_assert!((x - a * m.scale).abs() < 1e-4 * (vdc + a.abs()));
                prop_assert!((y - b * m.scale).abs() < 1e-4 * (vdc + b.abs()));
                prop_assert!(m.scale > 0.0 && m.scale <= 1.0);
            }
        }
    }
}
