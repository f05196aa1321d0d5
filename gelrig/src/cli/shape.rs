//! `gelrig shape`: the GelSight as a shape sensor. `gelrig shape calibrate DIR` fits the map
//! from colour change to slope on ball presses; `gelrig shape FRAME…` writes height maps.

use std::path::PathBuf;

use crate::cli::Exit;
use crate::shape::{
    CirclesFrom, ModelKind, ShapeFile, ShapeFileError, calibrate_dir, write_height_maps,
};

/// Height maps from frames (`gelrig shape FRAME… --model shape.yaml --background BG.png --out
/// DIR`), or a calibration on ball presses (`gelrig shape calibrate DIR …`).
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub(crate) struct Cmd {
    #[command(subcommand)]
    action: Option<Action>,
    /// Frames (PNG) to read into height maps.
    #[arg(required = true)]
    frames: Vec<PathBuf>,
    /// The shape file `gelrig shape calibrate` wrote.
    #[arg(long, value_name = "SHAPE.yaml", required = true)]
    model: Option<PathBuf>,
    /// A frame of the unpressed gel from the same session as the frames (the lights and the
    /// camera drift between sessions).
    #[arg(long, value_name = "PNG", required = true)]
    background: Option<PathBuf>,
    /// Directory receiving `<frame>.height.npy`, `<frame>.height.png` and `shape.csv`.
    #[arg(long, value_name = "DIR", required = true)]
    out: Option<PathBuf>,
    /// Use this model instead of the file's chosen one.
    #[arg(long = "slope-model", value_parser = ["local-linear", "lut"])]
    slope_model: Option<String>,
    /// Also write `<frame>.ply` point clouds (mm).
    #[arg(long)]
    ply: bool,
}

#[derive(clap::Subcommand)]
enum Action {
    /// Fit the map from colour change to slope on ball presses: DIR holds `background.png`,
    /// the presses, and `labels.csv` (file, center_x_px, center_y_px, contact_radius_px)
    /// where the contact circles were labelled by hand; without it every other PNG is a
    /// press and its circle is found in the image (and printed).
    Calibrate(Calibrate),
}

#[derive(clap::Args)]
struct Calibrate {
    /// Directory of ball presses.
    dir: PathBuf,
    /// The ball's diameter, e.g. `9.47mm`.
    #[arg(long, value_parser = parse_mm)]
    ball_diameter: f64,
    /// Image scale, mm per pixel.
    #[arg(long)]
    mm_per_px: f64,
    /// The shape file to write.
    #[arg(long, value_name = "SHAPE.yaml")]
    out: PathBuf,
}

fn parse_mm(s: &str) -> Result<f64, String> {
    let t = s.trim();
    let n = t.strip_suffix("mm").unwrap_or(t).trim();
    n.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0)
        .ok_or_else(|| format!("{s:?} is not a length: give millimetres, e.g. 9.47mm"))
}

impl Cmd {
    pub(crate) fn run(self) -> anyhow::Result<Exit> {
        match self.action {
            Some(Action::Calibrate(c)) => c.run(),
            None => self.read(),
        }
    }

    fn read(self) -> anyhow::Result<Exit> {
        let (Some(model), Some(background), Some(out)) = (self.model, self.background, self.out)
        else {
            err!("error: --model, --background and --out are needed; see `gelrig shape --help`");
            return Ok(Exit::from(super::EXIT_INVALID));
        };
        let which = self.slope_model.as_deref().map(|m| match m {
            "lut" => ModelKind::Lut,
            _ => ModelKind::LocalLinear,
        });
        let file = match ShapeFile::read(&model) {
            Ok(f) => f,
            Err(e) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        match write_height_maps(&file, which, &background, &self.frames, &out, self.ply) {
            Ok(rows) => {
                out!(
                    "{} height map{} in {} (model {}; shape.csv: depth, contact area, centroid, volume)",
                    rows.len(),
                    if rows.len() == 1 { "" } else { "s" },
                    out.display(),
                    which.unwrap_or(file.chosen).name()
                );
                for r in &rows {
                    out!(
                        "  {}: deepest {:.3} mm, contact {:.2} mm², volume {:.4} mm³",
                        r.file,
                        r.max_depth_mm,
                        r.contact_area_mm2,
                        r.volume_mm3
                    );
                }
                Ok(Exit::SUCCESS)
            }
            Err(e @ ShapeFileError::Write { .. }) => Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                Ok(Exit::from(super::EXIT_INVALID))
            }
        }
    }
}

impl Calibrate {
    fn run(self) -> anyhow::Result<Exit> {
        if !(self.mm_per_px.is_finite() && self.mm_per_px > 0.0) {
            err!(
                "error: --mm-per-px {} is not a scale; fix: give the image's mm per pixel",
                self.mm_per_px
            );
            return Ok(Exit::from(super::EXIT_INVALID));
        }
        let file = match calibrate_dir(&self.dir, self.ball_diameter, self.mm_per_px) {
            Ok(f) => f,
            Err(e @ ShapeFileError::Write { .. }) => return Err(e.into()),
            Err(e) => {
                err!("error: {e}");
                return Ok(Exit::from(super::EXIT_INVALID));
            }
        };
        out!(
            "calibrated on {} ball presses ({}×{} px, ball {} mm, {} mm/px); each press read by models fitted without it:",
            file.presses.len(),
            file.width_px,
            file.height_px,
            file.ball_diameter_mm,
            file.mm_per_px
        );
        for f in &file.figures {
            let h = &f.held_out;
            out!(
                "  {:<12} cap height {:.1} % median, {:.1} % worst ({}); sphere radius {:.1} % / {:.1} %; slope rms {:.1}° (median); spurious depth beyond the contact ≤ {:.2} of the cap; {:.2} ms a frame",
                h.model.name(),
                h.height_median_pct,
                h.height_worst_pct,
                h.height_worst_press,
                h.radius_median_pct,
                h.radius_worst_pct,
                h.slope_rms_median_deg,
                h.spurious_worst,
                f.ms_per_frame
            );
        }
        match file.circles_from {
            CirclesFrom::Labels => {
                out!("  circles: labels.csv's, each checked against the circle in the image")
            }
            CirclesFrom::Image => {
                out!("  circles: found in the image (no labels.csv); check them:");
                for p in &file.presses {
                    out!(
                        "    {}: centre ({:.1}, {:.1}) px, radius {:.1} px",
                        p.file,
                        p.circle.x_px,
                        p.circle.y_px,
                        p.circle.radius_px
                    );
                }
            }
        }
        for l in &file.left_out {
            out!("  left out {}: {}", l.file, l.reason);
        }
        out!("chosen: {} ({})", file.chosen.name(), file.chosen_by);
        file.write(&self.out)?;
        out!("wrote {}", self.out.display());
        Ok(Exit::SUCCESS)
    }
}
