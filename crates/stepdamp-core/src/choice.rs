//! Named choices (modes, compensations): one table of names gives `name()`, `ALL`,
//! `FromStr` and `Display`, so the command line, the profile and the results use the same
//! words.

/// A name that is none of a choice's names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownName {
    /// What was being named, e.g. `"mode"`.
    pub what: &'static str,
    /// The names allowed, comma-separated.
    pub expected: &'static str,
}

impl core::fmt::Display for UnknownName {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "unknown {}: expected {}", self.what, self.expected)
    }
}

impl core::error::Error for UnknownName {}

/// Names, `FromStr` and `Display` of a choice, from one table: for a fieldless enum of the
/// calling crate,
/// `named_choice!(Effort, "effort", "measured, command", [MeasuredIq => "measured", CommandIq => "command"])`
/// defines `Effort::ALL` (every choice, in table order), `Effort::name`, `FromStr` (the
/// names only; the error is an [`UnknownName`] with the what and the expected list given
/// here) and `Display` (the name). The library crates name their option sets with it, so
/// that a front end lists and parses a choice from its own table.
#[macro_export]
macro_rules! named_choice {
    ($ty:ident, $what:literal, $expected:literal, [$($v:ident => $n:literal),+ $(,)?]) => {
        impl $ty {
            /// Every choice, in table order.
            pub const ALL: &'static [$ty] = &[$($ty::$v),+];

            /// The name in tables, profiles and on the command line.
            pub const fn name(self) -> &'static str {
                match self {
                    $($ty::$v => $n),+
                }
            }
        }

        impl core::str::FromStr for $ty {
            type Err = $crate::choice::UnknownName;
            fn from_str(s: &str) -> Result<Self, $crate::choice::UnknownName> {
                match s {
                    $($n => Ok($ty::$v),)+
                    _ => Err($crate::choice::UnknownName { what: $what, expected: $expected }),
                }
            }
        }

        impl core::fmt::Display for $ty {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}
