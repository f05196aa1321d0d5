//! A directory of ball presses: `background.png`, the presses, and `labels.csv` (`file,
//! center_x_px, center_y_px, contact_radius_px`: the contact circle of each press, by hand).
//! Without `labels.csv`, every other PNG in the directory is a press and its circle is found
//! in the image ([`shape::find_circle`]); with it, each labelled circle is checked against
//! the one in the image, and a press whose label is not where its ball is, is left out.

use std::path::Path;

use shape::Rgb;
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
    /// Where the circles came from.
    pub circles_from: CirclesFrom,
}

/// Where a calibration's contact circles came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CirclesFrom {
    /// `labels.csv`, by hand (each checked against the image).
    Labels,
    /// Found in the image: no `labels.csv`.
    Image,
}

/// A labelled centre farther than this share of the labelled radius from the circle found
/// in the image is not where the ball is. The finder's centre is within 5 px of the hand
/// labels on every real Mini press (shape/tests/find_circle.rs), a sixth of a contact's
/// radius; the copied label of `press_50` is 3 radii off.
const LABEL_OFF_SHARE: f64 = 0.5;

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
        return found_presses(dir, background);
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
        let px = read_press(&dir.join(&name), &background)?;
        if let Some(reason) = label_off(&background, &px, &circle) {
            left_out.push((name, reason));
            continue;
        }
        presses.push((name, px, circle));
    }
    Ok(BallPresses {
        background,
        presses,
        left_out,
        circles_from: CirclesFrom::Labels,
    })
}

/// Why a labelled circle is not where the image shows the ball, if it is not.
fn label_off(background: &(usize, usize, Vec<u8>), px: &[u8], label: &Circle) -> Option<String> {
    let (w, h, bg) = background;
    let found = shape::find_circle(Rgb::new(*w, *h, bg).ok()?, Rgb::new(*w, *h, px).ok()?);
    match found {
        Ok(c) => {
            let off = (c.x_px - label.x_px).hypot(c.y_px - label.y_px);
            (off > LABEL_OFF_SHARE * label.radius_px).then(|| {
                format!(
                    "its label's centre ({:.0}, {:.0}) is {off:.0} px from the circle in the \
                     image ({:.0}, {:.0}, radius {:.0} px): fix the label",
                    label.x_px, label.y_px, c.x_px, c.y_px, c.radius_px
                )
            })
        }
        Err(e) => Some(format!("{e}")),
    }
}

/// Every PNG of `dir` but the background, each with the circle found in it; a press where
/// none is found is left out with the reason.
fn found_presses(
    dir: &Path,
    background: (usize, usize, Vec<u8>),
) -> Result<BallPresses, ShapeFileError> {
    let listing = std::fs::read_dir(dir).map_err(|e| {
        bad(
            dir,
            e.to_string(),
            "give a directory of ball presses and background.png",
        )
    })?;
    let mut names: Vec<String> = listing
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.to_ascii_lowercase().ends_with(".png") && n != "background.png")
        .collect();
    names.sort();
    if names.is_empty() {
        return Err(bad(
            dir,
            "no presses (PNG files other than background.png)",
            "put the ball presses in the directory (docs/how-to/calibrate-shape.md)",
        ));
    }
    let (w, h, bg) = &background;
    let bg_rgb = Rgb::new(*w, *h, bg)?;
    let mut presses = Vec::new();
    let mut left_out = Vec::new();
    for name in names {
        let path = dir.join(&name);
        let px = read_press(&path, &background)?;
        match shape::find_circle(bg_rgb, Rgb::new(*w, *h, &px)?) {
            Ok(circle) => presses.push((name, px, circle)),
            Err(e) => left_out.push((name, e.to_string())),
        }
    }
    Ok(BallPresses {
        background,
        presses,
        left_out,
        circles_from: CirclesFrom::Image,
    })
}

/// A press's pixels, refused where it cannot be read or is not the background's size.
fn read_press(
    path: &Path,
    background: &(usize, usize, Vec<u8>),
) -> Result<Vec<u8>, ShapeFileError> {
    let (w, h, px) = load_rgb(path).map_err(|e| {
        bad(
            path,
            e.to_string(),
            "a press must be a readable PNG of the sensor",
        )
    })?;
    if (w, h) != (background.0, background.1) {
        return Err(bad(
            path,
            format!(
                "{w}×{h} px, the background {}×{} px",
                background.0, background.1
            ),
            "calibrate on frames of one camera setting",
        ));
    }
    Ok(px)
}
