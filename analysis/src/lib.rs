//! Pure analysis of recorded gelrig data.
//!
//! This crate turns what a run recorded — force samples, stage positions, GelSight frames —
//! into the thesis's results: marker positions and identities, displacement fields and their
//! decomposition (thesis §3.4, ch. 4–6), relaxation fits and quasistatic values, linearity,
//! hysteresis, slip cues and force from the field (§4.3–4.4).
//!
//! It is deliberately free of I/O, async and device code: every function takes data in
//! memory and returns data, so the same code runs on a live rig, on a dry run and on a run
//! directory from years ago, and is tested against the simulator's known truth. It depends
//! only on `mechanics`, for the reference fields it fits against.
//!
//! Modules:
//! - [`tracking`]: marker detection, identity across frames, weighted Lucas–Kanade.
//! - [`field`]: dense displacement fields, their pictures and their decomposition.
//! - [`relaxation`]: F∞ and τ of a step's relaxation by variable projection; Aitken.

pub mod field;
pub mod relaxation;
pub mod tracking;
