//! Offline work on run directories: the GelSight as a force sensor ([`sensor`]: calibrate it
//! from runs, read the wrench of any recording), the user's own gel ([`material`]: fit its
//! modulus, relaxation and Poisson's ratio to a bench's runs), tracking of recorded frames
//! ([`track`]: image files or a run's frames into `markers.csv`), and a run read whole for
//! them ([`run_data`], tracking its frames first where it has none tracked).

pub mod material;
pub mod run_data;
pub mod sensor;
pub mod shape;
pub mod track;
