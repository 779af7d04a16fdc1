//! Physics tests of the closed loop against theory.
