//! Park and inverse Park transforms between the stationary phase frame (a, b) of a
//! two-phase motor and the rotating (d, q) frame at electrical angle `θe`.
//!
//! `d = a cos θe + b sin θe`, `q = −a sin θe + b cos θe`; inverse
//! `a = d cos θe − q sin θe`, `b = d sin θe + q cos θe`. A positive `q` current makes
//! positive torque `τ = Km·i_q` when the frame is aligned with the rotor (docs/design.md#the-plant).
//! Cost: 4 multiplies and 2 adds each, given `(sin θe, cos θe)`. Round-trip error: a few
//! ulp of the inputs' magnitude.

/// A vector in the rotating frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dq {
    /// Direct axis component.
    pub d: f32,
    /// Quadrature (torque) axis component.
    pub q: f32,
}

/// A vector in the stationary two-phase frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ab {
    /// Phase A component.
    pub a: f32,
    /// Phase B component.
    pub b: f32,
}

/// Park transform with `(sin θe, cos θe)` given.
#[inline]
pub fn park(x: Ab, sin: f32, cos: f32) -> Dq {
    Dq { d: x.a * cos + x.b * sin, q: -x.a * sin + x.b * cos }
}

/// Inverse Park transform with `(sin θe, cos θe)` given.
#[inline]
pub fn inverse_park(x: Dq, sin: f32, cos: f32) -> Ab {
    Ab { a: x.d * cos - x.q * sin, b: x.d * sin + x.q * cos }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn d_axis_is_phase_a_at_zero_angle() {
        let dq = park(Ab { a: 1.5, b: 0.0 }, 0.0, 1.0);
        assert_eq!(dq, Dq { d: 1.5, q: 0.0 });
        // A quarter turn on, the d axis lies along phase B.
        let dq = park(Ab { a: 0.0, b: 2.0 }, 1.0, 0.0);
        assert_eq!(dq, Dq { d: 2.0, q: 0.0 });
    }

    #[test]
    fn q_axis_sign_matches_design_section_3() {
        // docs/design.md#the-plant: i_q = −i_a sin θe + i_b cos θe.
        // θe = π/2 (sin 1, cos 0): phase A current is −q, phase B current is +d.
        assert_eq!(park(Ab { a: 1.0, b: 0.0 }, 1.0, 0.0), Dq { d: 0.0, q: -1.0 });
        assert_eq!(park(Ab { a: 0.0, b: 1.0 }, 1.0, 0.0), Dq { d: 1.0, q: 0.0 });
        // θe = 0: phase B current is +q.
        assert_eq!(park(Ab { a: 0.0, b: 1.0 }, 0.0, 1.0), Dq { d: 0.0, q: 1.0 });
        // θe = −π/2: phase A current is +q.
        assert_eq!(park(Ab { a: 1.0, b: 0.0 }, -1.0, 0.0), Dq { d: 0.0, q: 1.0 });
        // Inverse: a q command at θe = 0 is a phase B voltage, at π/2 a negative phase A one.
        assert_eq!(inverse_park(Dq { d: 0.0, q: 2.0 }, 0.0, 1.0), Ab { a: 0.0, b: 2.0 });
        assert_eq!(inverse_park(Dq { d: 0.0, q: 2.0 }, 1.0, 0.0), Ab { a: -2.0, b: 0.0 });
    }

    proptest! {
        #[test]
        fn park_matches_the_design_formula(
            a in -100.0f32..100.0, b in -100.0f32..100.0, th in -10.0f32..10.0
        ) {
            let (s, c) = (libm::sinf(th), libm::cosf(th));
            let x = park(Ab { a, b }, s, c);
            prop_assert_eq!(x.q, -a * s + b * c);
            prop_assert_eq!(x.d, a * c + b * s);
        }

        #[test]
        fn park_then_inverse_park_is_identity(
            d in -100.0f32..100.0, q in -100.0f32..100.0, th in -10.0f32..10.0
        ) {
            let (s, c) = (libm::sinf(th), libm::cosf(th));
            let back = park(inverse_park(Dq { d, q }, s, c), s, c);
            let tol = 1e-5 * (1.0 + d.abs() + q.abs());
            prop_assert!((back.d - d).abs() <= tol && (back.q - q).abs() <= tol);
        }

        #[test]
        fn park_preserves_the_vector_length(
            a in -100.0f32..100.0, b in -100.0f32..100.0, th in -10.0f32..10.0
        ) {
            let dq = park(Ab { a, b }, libm::sinf(th), libm::cosf(th));
            let l0 = libm::hypotf(a, b);
            prop_assert!((libm::hypotf(dq.d, dq.q) - l0).abs() <= 1e-5 * (1.0 + l0));
        }
    }
}
