//! Pure analysis of recorded gelrig data.
//!
//! This crate turns what a run recorded — force samples, stage positions, marker fields
//! tracked from GelSight frames (the `tracking` crate) — into the thesis's results:
//! relaxation fits and quasistatic values, linearity, hysteresis, slip cues and the GelSight
//! as a force sensor (thesis ch. 4–6).
//!
//! It is deliberately free of I/O, async and device code: every function takes data in
//! memory and returns data, so the same code runs on a live rig, on a dry run and on a run
//! directory from years ago, and is tested against the simulator's known truth. It depends
//! only on `mechanics`, for the reference fields it fits against, and on `tracking`, for the
//! marker field.
//!
//! Modules:
//! - [`relaxation`]: F∞ and τ of a step's relaxation by variable projection, the number
//!   of terms by BIC, trust flags, time constants pooled over steps, settle error; Aitken.
//! - [`equilibrium`]: F∞ while a step relaxes, with an honest uncertainty; learned time
//!   constants.
//! - [`carried_relaxation`]: a later step's slowest term carried from the load history.
//! - [`settle_rules`]: the rate and adaptive settle rules as pure functions, replayed by
//!   reports; the gel's memory.
//! - [`linearity`]: line fits, the linear range, the power law of curved indenters.
//! - [`hysteresis`]: loading against unloading.
//! - [`slip`]: stick, incipient slip and slip per step from three cues.
//! - [`field_force`]: force from the displacement field against a reference field.
//! - [`force_sensor`]: the GelSight's wrench from its field (moments, traction map, scale
//!   fit; ridge with GCV; the gel's memory).
//! - [`tactile`]: a grasp's slip state frame by frame (stick, incipient, slip).
//! - [`material_fit`]: a gel's E∞, Prony terms and contact offsets from pressing records.
//! - [`frame_timing`]: a camera's frame intervals, drops and duplicates, exposure matching.

pub mod carried_relaxation;
pub mod equilibrium;
pub mod field_force;
pub mod force_sensor;
pub mod frame_timing;
pub mod hysteresis;
pub mod linearity;
pub mod material_fit;
pub mod relaxation;
pub mod settle_rules;
pub mod slip;
pub mod tactile;
