//! The user's own gel: a material fitted to a bench's runs (`gelrig fit-material`), its
//! file, and how a protocol takes it in (`material: {from: MATERIAL.yaml}`).

mod field_nu;
pub mod fit;
mod law;
mod nu_choice;
pub mod poisson;
mod run;

pub use experiments::protocol::material_file as file;
pub use experiments::protocol::material_file::{MaterialFile, MaterialFileError};
pub use fit::{FitError, fit};
