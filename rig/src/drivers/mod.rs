//! Drivers for real devices, each behind a device trait and each with a twin in
//! [`crate::twins`] that speaks the same wire protocol over a real transport.

pub mod image_folder;
pub mod manual;
pub mod netft;
pub mod netft_rdt;
pub mod zaber;
pub mod zaber_ascii;
