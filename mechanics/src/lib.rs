//! Contact mechanics and viscoelasticity of the GelSight elastomer.
//!
//! gelrig needs one physical model in two places: the simulated bench (so a dry run
//! produces the forces and marker fields a real bench would) and the analysis core (which
//! fits measured fields against reference fields, thesis §4.3–4.4). Keeping that model here,
//! pure and deterministic, means both sides agree by construction and the model can be tested
//! against closed-form oracles (`../shared/specs/mechanics.md` §5) without any device or file.
//!
//! Units throughout: millimetres, newtons, seconds, degrees where named `_deg` (radians
//! otherwise), and moduli in MPa (= N/mm²), so a force comes out in N without conversion.
//!
//! Modules:
//! - [`geometry`]: the elastomer layer, its material, and the indenter shapes of the thesis.
//! - [`viscoelastic`]: Prony series (generalised Maxwell) with the exact exponential update.
//! - [`contact`]: quasistatic normal, tangential and torsional contact laws on a bonded layer.
//! - [`field`]: in-plane surface displacement fields under normal, shear and torsional load.
//! - [`greens`]: Green's functions of the surface — half-space point loads and the bonded
//!   layer's compliance in Fourier space.
//! - [`operator`]: surface compliance operators on a grid of cells, by FFT ([`fft2`]).
//! - [`solve`]: contact solvers on a grid — known area, unknown area (Polonsky–Keer).
//! - [`punch`]: the flat circular punch on a bonded layer, semi-analytically (Hayes et al.
//!   1972).
//! - [`friction`]: Cattaneo–Mindlin partial slip in closed form and the plant's hysteretic
//!   friction element.
//! - [`pressing`]: flat and curved indenters pressed with Coulomb friction (coupled normal–
//!   tangential contact), along their loading path.
//! - [`unloading`]: a curved contact that shrinks, viscoelastically (Ting 1966, by MDR).
//! - [`finite_strain`]: how much stiffer a neo-Hookean gel presses than small strain says.
//! - [`response`]: the contact model precomputed from the solvers, fast enough for every
//!   force sample of a dry run.

pub mod contact;
pub mod fft2;
pub mod field;
pub mod finite_strain;
pub mod friction;
pub mod geometry;
pub mod greens;
pub mod operator;
#[cfg(test)]
mod oracles;
pub mod pressing;
pub mod punch;
pub mod response;
pub mod solve;
pub mod unloading;
pub mod viscoelastic;

pub use geometry::{Indenter, Layer, Material};
pub use viscoelastic::{Prony, PronyState, PronyTerm, ramp_factor};

/// Why a mechanics computation refused its input.
///
/// The plant and the analysis core pass user-written parameters through here, so bad values
/// surface as errors with the offending quantity, never as NaN forces.
#[derive(Debug, Clone, PartialEq)]
pub enum MechanicsError {
    /// A parameter is outside its physical range (name, value, the allowed range).
    OutOfRange {
        /// Parameter name with its unit, e.g. `thickness_mm`.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The allowed range, in words.
        allowed: &'static str,
    },
}

impl std::fmt::Display for MechanicsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MechanicsError::OutOfRange {
                name,
                value,
                allowed,
            } => write!(f, "{name} = {value} is outside its range ({allowed})"),
        }
    }
}

impl std::error::Error for MechanicsError {}

/// Checks that `value` is finite and within `[lo, hi]` (inclusive ends chosen by caller).
pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    ok: bool,
    allowed: &'static str,
) -> Result<(), MechanicsError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(MechanicsError::OutOfRange {
            name,
            value,
            allowed,
        })
    }
}
