//! `gelrig fit-material`.

use crate::cli::Exit;
use std::path::PathBuf;

use crate::material::{MaterialFileError, fit};

/// Fit the gel's relaxed modulus, its relaxation, its Poisson's ratio where the runs tell it
/// and its friction to recorded runs; write a material file a protocol takes with
/// `material: {from: MATERIAL.yaml}`.
#[derive(clap::Args)]
pub(crate) struct Cmd {
    /// Runs of one gel: stepped pressing runs (modulus, relaxation, contact offset; ν from
    /// the marker field around a flat circular punch where frames were recorded — tracked
    /// into the run's `markers.csv` first if it has none — or from the forces of two flat
    /// punch sizes) and shear runs that reach slip (friction).
    #[arg(value_name = "RUN_DIR", required = true)]
    runs: Vec<PathBuf>,
    /// The material file to write.
    #[arg(long, value_name = "MATERIAL.yaml")]
    out: PathBuf,
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        let file = match fit(&self.runs) {
            Ok(f) => f,
            Err(e) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        if let Err(e @ MaterialFileError::Write { .. }) = file.write(&self.out) {
            return Err(e.into());
        }
        let m = &file.material;
        let u = &file.uncertainty;
        match u.poisson_ratio {
            Some(sd) => out!(
                "E∞ = {:.4} ± {:.4} MPa, ν = {:.4} ± {sd:.4} ({})",
                m.youngs_modulus.mpa(),
                u.youngs_modulus_mpa,
                m.poisson_ratio,
                if file
                    .provenance
                    .iter()
                    .any(|p| p.starts_with("poisson_ratio:") && p.contains("marker field"))
                {
                    "from the marker field around the flat punch"
                } else {
                    "where the indenters' moduli agree"
                }
            ),
            None => out!(
                "E∞ = {:.4} ± {:.4} MPa (ν held at {})",
                m.youngs_modulus.mpa(),
                u.youngs_modulus_mpa,
                m.poisson_ratio
            ),
        }
        for (t, s) in m.prony.iter().zip(&u.prony) {
            out!(
                "  Prony term: weight {:.4} ± {:.4}, τ {:.3} ± {:.3} s",
                t.weight,
                s.weight,
                t.tau.s(),
                s.tau_s
            );
        }
        match u.friction {
            Some(sd) => out!(
                "μ static {:.3} ± {sd:.3}, sliding {:.3}",
                m.friction,
                m.kinetic_friction.unwrap_or(m.friction)
            ),
            None => out!("μ held at {} (no run reached gross slip)", m.friction),
        }
        for r in &file.fitted_on {
            if let (Some(d0), Some(rms)) = (r.contact_offset_mm, r.residual_rms_n) {
                out!(
                    "  {}: contact {:+.4} ± {:.4} mm from the recorded origin, residual rms \
                     {rms:.4} N over {} samples",
                    r.run,
                    d0,
                    r.contact_offset_sd_mm.unwrap_or(0.0),
                    r.samples.unwrap_or(0)
                );
            }
        }
        out!("wrote {}", self.out.display());
        Ok(Exit::SUCCESS)
    }
}
