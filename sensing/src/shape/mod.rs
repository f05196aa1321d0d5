//! Shape from the GelSight's light, on files (issue 50): `gelrig shape calibrate` reads a
//! directory of ball presses into a shape file ([`file`]), and `gelrig shape` reads frames
//! into height maps ([`maps`]). The numerics are the `shape` crate's.

pub mod file;
pub mod maps;
pub mod presses;

pub use file::{ShapeFile, ShapeFileError};
pub use maps::{ShapeRow, write_height_maps};
pub use presses::{BallPresses, CirclesFrom, read_presses};
pub mod calibrate;
pub use calibrate::calibrate_dir;
