//! # stepdamp-identify
//!
//! Identification of detent harmonics and friction (design.md §5). Under construction.
