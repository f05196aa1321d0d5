//! Drivers for real devices, each behind a device trait and each with a twin in
//! [`crate::twins`] that speaks the same wire protocol over a real transport.

pub mod ati_can;
pub mod can;
pub mod image_folder;
pub mod manual;
pub mod modbus;
pub mod netft;
pub mod netft_rdt;
mod serial_async;
mod serial_line;
pub mod smc100;
#[cfg(feature = "v4l")]
pub mod v4l2;
pub mod zaber;
pub mod zaber_ascii;
