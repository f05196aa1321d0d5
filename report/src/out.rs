//! A report folder being written: its sections, its plots (SVG + PNG), and the small
//! formatting helpers every section uses. The leaf the report's writers share.

use std::fs;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use super::ReportError;
use super::plots::{Chart, SIZE, rgb, svg};

pub(super) fn werr(path: &Path) -> impl Fn(String) -> ReportError + '_ {
    move |detail| ReportError::Write {
        path: path.to_path_buf(),
        detail,
    }
}

/// A section of the report: a title, markdown text and plots.
pub(super) struct Section {
    pub(super) title: String,
    pub(super) text: String,
    pub(super) plots: Vec<String>,
}

pub(super) struct Out {
    pub(super) dir: PathBuf,
    pub(super) sections: Vec<Section>,
}

impl Out {
    /// Writes `name.svg` and `name.png` and returns the name.
    pub(super) fn plot(&self, name: &str, chart: &Chart) -> Result<String, ReportError> {
        let s = svg(chart).map_err(werr(&self.dir.join(format!("{name}.svg"))))?;
        let p = self.dir.join(format!("{name}.svg"));
        fs::write(&p, s).map_err(|e| werr(&p)(e.to_string()))?;
        let px = rgb(chart).map_err(werr(&self.dir.join(format!("{name}.png"))))?;
        let p = self.dir.join(format!("{name}.png"));
        image::RgbImage::from_raw(SIZE.0, SIZE.1, px)
            .ok_or_else(|| werr(&p)("plot buffer size".into()))?
            .save(&p)
            .map_err(|e| werr(&p)(e.to_string()))?;
        Ok(name.to_string())
    }
}

pub(super) fn f(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "—".into()
    }
}

pub(super) fn num(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}
