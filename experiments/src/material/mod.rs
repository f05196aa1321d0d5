//! The user's own gel: a material fitted to a bench's runs (`gelrig fit-material`), its
//! file, and how a protocol takes it in (`material: {from: MATERIAL.yaml}`).

mod field_nu;
pub mod file;
pub mod fit;
mod law;
pub mod poisson;

pub use file::{MaterialFile, MaterialFileError};
pub use fit::{FitError, fit};
