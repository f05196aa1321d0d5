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
//! - [`relaxation`]: F∞ and τ of a step's relaxation by variable projection, the number
//!   of terms by BIC, trust flags, time constants pooled over steps, settle error; Aitken.
//! - [`linearity`]: line fits, the linear range, the power law of curved indenters.
//! - [`hysteresis`]: loading against unloading.
//! - [`slip`]: stick, incipient slip and slip per step from three cues.
//! - [`field_force`]: force from the displacement field against a reference field.
//! - [`tactile`]: a grasp's slip state frame by frame (stick, incipient, slip).
//! - [`frame_timing`]: a camera's frame intervals, drops and duplicates, exposure matching.

pub mod carried_relaxation;
pub mod equilibrium;
pub mod field;
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
pub mod tracking;
