//! A directory of ball presses: `background.png`, the presses, and `labels.csv` (`file,
//! center_x_px, center_y_px, contact_radius_px`: the contact circle of each press, by hand).

use std::path::{Path, PathBuf};

use shape::ball::Circle;

use super::ShapeFileError;
use crate::track::load_rgb;

/// The presses as read, and those left out with the reason.
#[derive(Debug)]
pub struct BallPresses {
    /// Background: width, height, RGB.
    pub background: (usize, usize, Vec<u8>),
    /// Each press: file name, pixels, circle.
    pub presses: Vec<(String, Vec<u8>, Circle)>,
    /// Presses left out, with why.
    pub left_out: Vec<(String, String)>,
}

fn bad(path: &Path, detail: impl Into<String>, fix: &'static str) -> ShapeFileError {
    ShapeFileError::Read {
        path: path.to_path_buf(),
        detail: detail.into(),
        fix,
    }
}

/// Reads `dir`'s background, labels and presses. A press whose circle repeats another's
/// exactly (a label copied from the press before) is left out and said so: its circle is
/// not where its ball is.
pub fn read_presses(dir: &Path) -> Result<BallPresses, ShapeFileError> {
    let bg_path = dir.join("background.png");
    let background = load_rgb(&bg_path).map_err(|e| {
        bad(
            &bg_path,
            e.to_string(),
            "put a frame of the unpressed gel, taken in the same session, at background.png",
        )
    })?;
    let labels_path = dir.join("labels.csv");
    if !labels_path.is_file() {
        return Err(bad(
            &labels_path,
            "no labels.csv: finding the circles in the image is not built yet",
            "label each press's contact circle (file,center_x_px,center_y_px,contact_radius_px; docs/how-to/calibrate-shape.md)",
        ));
    }
    let mut rd = csv::Reader::from_path(&labels_path)
        .map_err(|e| bad(&labels_path, e.to_string(), "check the file"))?;
    let mut presses: Vec<(String, Vec<u8>, Circle)> = Vec::new();
    let mut left_out = Vec::new();
    for (line, rec) in rd.records().enumerate() {
        let rec = rec.map_err(|e| bad(&labels_path, e.to_string(), "check the file"))?;
        let field = |i: usize| -> Result<f64, ShapeFileError> {
            rec.get(i)
                .and_then(|v| v.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    bad(
                        &labels_path,
                        format!("line {}: column {} is not a number", line + 2, i + 1),
                        "each row is file,center_x_px,center_y_px,contact_radius_px",
                    )
                })
        };
        let name = rec.get(0).unwrap_or_default().trim().to_string();
        let circle = Circle {
            x_px: field(1)?,
            y_px: field(2)?,
            radius_px: field(3)?,
        };
        if circle.radius_px <= 2.0 {
            return Err(bad(
                &labels_path,
                format!("line {}: contact radius {} px", line + 2, circle.radius_px),
                "label the contact circle's radius in pixels",
            ));
        }
        if let Some(other) = presses
            .iter()
            .find(|p| p.2.x_px == circle.x_px && p.2.y_px == circle.y_px)
        {
            left_out.push((
                name,
                format!("its circle's centre is {}'s (a label copied?)", other.0),
            ));
            continue;
        }
        let path: PathBuf = dir.join(&name);
        let (w, h, px) = load_rgb(&path).map_err(|e| {
            bad(
                &path,
                e.to_string(),
                "labels.csv names a frame that cannot be read",
            )
        })?;
        if (w, h) != (background.0, background.1) {
            return Err(bad(
                &path,
                format!(
                    "{w}×{h} px, the background {}×{} px",
                    background.0, background.1
                ),
                "calibrate on frames of one camera setting",
            ));
        }
        presses.push((name, px, circle));
    }
    Ok(BallPresses {
        background,
        presses,
        left_out,
    })
}
