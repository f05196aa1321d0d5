//! Traction-map pictures and their time course (`gelrig track … --traction DIR`): for each
//! frame with a contact region, the traction that explains the markers' field (the normal
//! traction as colour, the tangential as arrows) in `traction_NNNNNN.svg`, and the map's
//! integrals per frame in `traction.csv`.
//!
//! With a `traction-map` sensor file the map is the calibrated one (its λ, scaled to the force
//! sensor by the model's gains). Without one — a recording from a sensor nobody calibrated,
//! such as the real GelSight Mini sequence — the map is solved at the nominal modulus
//! (1 MPa) with one λ for the recording (the median of GCV's choices over its frames): its
//! shape and time course are real, its units are not (a real gel's modulus is unknown until
//! calibrated).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use analysis::force_sensor::Layout;
use analysis::force_sensor::ridge::LinearModel;
use analysis::force_sensor::traction::{TractionKernel, TractionMap};
use serde::Serialize;

use super::file::TractionSettings;
use super::reader::traction_map;
use super::{RunFrame, SensorError, SensorFile};

/// How to make the maps.
pub enum MapSource<'a> {
    /// A calibrated `traction-map` sensor.
    Sensor(&'a SensorFile),
    /// Uncalibrated: the gel's thickness and the image scale.
    Nominal {
        /// Elastomer thickness, mm.
        thickness_mm: f64,
        /// Image scale, mm per px.
        mm_per_px: f64,
    },
}

/// One row of `traction.csv`.
#[derive(Debug, Clone, Serialize)]
pub struct TractionRow {
    /// Frame number.
    pub frame: u64,
    /// Time on the run's timebase, where known.
    pub t_ns: Option<u64>,
    /// The wrench: calibrated, the sensor's reading of the map's integrals (as in
    /// `wrench.csv`), in N and N·mm; uncalibrated, the integrals at the nominal modulus.
    pub fx: f64,
    /// See `fx`.
    pub fy: f64,
    /// See `fx`.
    pub fz: f64,
    /// See `fx`.
    pub tz: f64,
    /// Whether the units are calibrated (else nominal: 1 MPa modulus).
    pub calibrated: bool,
    /// Regularisation used.
    pub lambda: f64,
    /// RMS misfit of the markers' displacement, µm.
    pub misfit_um: f64,
}

/// Writes the maps of `frames` (frame 0 the reference) into `dir`; returns the rows written
/// to `dir/traction.csv`.
pub fn write_maps(
    source: &MapSource<'_>,
    frames: &[RunFrame],
    dir: &Path,
) -> Result<Vec<TractionRow>, SensorError> {
    let werr = |path: PathBuf, e: String| SensorError::Write { path, detail: e };
    std::fs::create_dir_all(dir).map_err(|e| werr(dir.to_path_buf(), e.to_string()))?;
    let Some(first) = frames.first() else {
        return Ok(Vec::new());
    };
    // The layout, the settings, the kernel, and the gains from nominal to calibrated.
    let model = match source {
        MapSource::Sensor(file) => Some(file.model()),
        MapSource::Nominal { .. } => None,
    };
    let (layout, settings, gains, calibrated) = match source {
        MapSource::Sensor(file) => {
            let Some(t) = file.traction else {
                return Err(super::unfit(
                    dir,
                    format!(
                        "the sensor file's method is {:?}, not traction-map",
                        file.method
                    ),
                    "calibrate with `gelrig calibrate --method traction` for traction pictures",
                ));
            };
            let (gains, g_elongation, term) = calibrated_gains(&file.model(), &file.features);
            (file.layout(), (t, None), (gains, g_elongation, term), true)
        }
        MapSource::Nominal {
            thickness_mm,
            mm_per_px,
        } => {
            let refs = first.field.reference_px.clone();
            let n = refs.len().max(1) as f64;
            let centre = [
                refs.iter().map(|p| p[0]).sum::<f64>() / n,
                refs.iter().map(|p| p[1]).sum::<f64>() / n,
            ];
            let t = TractionSettings {
                thickness_mm: *thickness_mm,
                kernel_dx_mm: (thickness_mm / 8.0).min(0.5),
                cell_mm: (thickness_mm / 2.0).clamp(0.5, 1.0),
                support: 1.3,
                ellipse: true,
                lambda: 0.0,
            };
            (
                Layout::new(refs, *mm_per_px, centre),
                (t, Some(())),
                ([1.0; 4], 0.0, false),
                false,
            )
        }
    };
    let (t, per_frame_gcv) = settings;
    let (gains, g_elongation, elongated) = gains;
    let map = layout
        .match_markers(&first.field.reference_px)
        .map_err(|source| SensorError::Model {
            path: dir.to_path_buf(),
            source,
        })?;
    let (lo, hi) = layout.reference_px.iter().fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        },
    );
    let reach = (hi[0] - lo[0]).hypot(hi[1] - lo[1]) * layout.mm_per_px;
    let kernel = TractionKernel::new(t.thickness_mm, t.kernel_dx_mm, reach);
    // Uncalibrated: one λ for the whole recording, the median of GCV's choices on every
    // fourth frame with contact (GCV frame by frame swings on a real gel's noisy field).
    let mut t = t;
    if per_frame_gcv.is_some() {
        let mut l: Vec<f64> = frames
            .iter()
            .filter(|f| f.contact.is_some())
            .step_by(4)
            .filter_map(|f| {
                let (u, _) = layout.displacements_mm(&f.field, &map);
                traction_map(&layout, &kernel, &t, &u, f.contact, None).map(|m| m.lambda)
            })
            .collect();
        l.sort_by(f64::total_cmp);
        t.lambda = l.get(l.len() / 2).copied().unwrap_or(0.0);
    }
    // Calibrated: the wrench as wrench.csv reads it, the gel's memory in its Fz (the map
    // itself is the traction that explains the field, the elastic one).
    let read: std::collections::BTreeMap<u64, [f64; 4]> = match source {
        MapSource::Sensor(file) => super::wrench::wrench_of_frames(file, frames, dir)?
            .into_iter()
            .map(|r| (r.frame, [r.fx_n, r.fy_n, r.fz_n, r.tz_nmm]))
            .collect(),
        MapSource::Nominal { .. } => Default::default(),
    };
    let mut rows = Vec::new();
    let mut csv = csv::Writer::from_path(dir.join("traction.csv"))
        .map_err(|e| werr(dir.join("traction.csv"), e.to_string()))?;
    for f in frames {
        let (u, _) = layout.displacements_mm(&f.field, &map);
        let Some(m) = traction_map(&layout, &kernel, &t, &u, f.contact, Some(t.lambda)) else {
            continue;
        };
        // Calibrated: the sensor's reading of these integrals (as in wrench.csv); nominal:
        // the integrals themselves.
        let w: Vec<f64> = match (&model, read.get(&f.frame)) {
            (Some(_), Some(r)) => r.to_vec(),
            (Some(model), None) => {
                let features =
                    super::reader::traction_features(Some(&m), f.contact.as_ref(), elongated);
                model.predict(&features).0
            }
            (None, _) => m.wrench.to_vec(),
        };
        let row = TractionRow {
            frame: f.frame,
            t_ns: (f.t_ns > 0).then_some(f.t_ns),
            fx: w[0],
            fy: w[1],
            fz: w[2],
            tz: w[3],
            calibrated,
            lambda: m.lambda,
            misfit_um: m.misfit_mm * 1e3,
        };
        let mut frame_gains = gains;
        frame_gains[2] = fz_gain(gains, g_elongation, f.contact.as_ref());
        let svg = picture(
            &m,
            &layout,
            frame_gains,
            calibrated,
            f.frame,
            [w[0], w[1], w[2]],
        );
        let path = dir.join(format!("traction_{:06}.svg", f.frame));
        std::fs::write(&path, svg).map_err(|e| werr(path, e.to_string()))?;
        csv.serialize(&row)
            .map_err(|e| werr(dir.join("traction.csv"), e.to_string()))?;
        rows.push(row);
    }
    csv.flush()
        .map_err(|e| werr(dir.join("traction.csv"), e.to_string()))?;
    Ok(rows)
}

/// From the map's integrals at the nominal modulus to the calibrated reading, per channel
/// (∂F_c/∂F̃_c: the model's own-channel weight over its feature scale), with the elongation
/// term's weight on F̃_z over its scale, and whether the model has that term (`features`
/// the sensor file's).
fn calibrated_gains(model: &LinearModel, features: &[String]) -> ([f64; 4], f64, bool) {
    let g = |c: usize| {
        model
            .channels
            .get(c)
            .and_then(|ch| ch.weights.get(c))
            .copied()
            .unwrap_or(1.0)
            / model.scale.get(c).copied().unwrap_or(1.0)
    };
    let term = features
        .iter()
        .position(|f| f == analysis::force_sensor::ELONGATION_FEATURE);
    let g_elongation = term.map_or(0.0, |j| {
        model
            .channels
            .get(2)
            .and_then(|ch| ch.weights.get(j))
            .copied()
            .unwrap_or(0.0)
            / model.scale.get(j).copied().unwrap_or(1.0)
    });
    ([g(0), g(1), g(2), g(3)], g_elongation, term.is_some())
}

/// The picture's gain on the normal traction of a frame with contact `region`: with the
/// elongation term Fz also moves with the map's Fz through it, by the frame's elongation,
/// ∂F_z/∂F̃_z = g(2) + e·(its weight over its scale).
fn fz_gain(gains: [f64; 4], g_elongation: f64, region: Option<&super::history::Region>) -> f64 {
    gains[2] + g_elongation * super::gather::elongation_of(region)
}

/// The map as SVG: cells coloured by normal traction (white → red, compressive), arrows of
/// the tangential traction, over the view's outline; 10 px per mm.
fn picture(
    m: &TractionMap,
    layout: &Layout,
    gains: [f64; 4],
    calibrated: bool,
    frame: u64,
    force: [f64; 3],
) -> String {
    let s = layout.mm_per_px;
    let (lo, hi) = layout.reference_px.iter().fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        },
    );
    let to_mm = |p: [f64; 2]| {
        [
            (p[0] - layout.centre_px[0]) * s,
            (p[1] - layout.centre_px[1]) * s,
        ]
    };
    let (a, b) = (to_mm(lo), to_mm(hi));
    // The view about 600 px wide, whatever its size in mm.
    let px_per_mm = 600.0 / (b[0] - a[0]).max(1e-6);
    const PX_PER_MM_MAX: f64 = 60.0;
    let px_per_mm = px_per_mm.min(PX_PER_MM_MAX);
    let (w, h) = (
        ((b[0] - a[0]) * px_per_mm + 40.0).max(760.0),
        (b[1] - a[1]) * px_per_mm + 70.0,
    );
    let x = |mm: f64| (mm - a[0]) * px_per_mm + 20.0;
    let y = |mm: f64| (mm - a[1]) * px_per_mm + 50.0;
    // Calibrated: kPa; nominal: MPa at the nominal modulus (shape only).
    let unit = if calibrated { 1e3 } else { 1.0 };
    let pz: Vec<f64> = m.traction.iter().map(|t| t[2] * gains[2] * unit).collect();
    let pmax = pz
        .iter()
        .fold(0.0f64, |acc, v| acc.max(v.abs()))
        .max(1e-300);
    let tmax = m
        .traction
        .iter()
        .map(|t| (t[0] * gains[0]).hypot(t[1] * gains[1]) * unit)
        .fold(0.0f64, f64::max)
        .max(1e-300);
    let mut out = String::new();
    let _ = write!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" font-family="sans-serif" font-size="12">"#
    );
    let _ = write!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = write!(
        out,
        r#"<text x="10" y="16">frame {frame}: normal traction (colour, max {pmax:.3} {u}) and tangential (arrows, max {tmax:.3} {u})</text>"#,
        u = if calibrated {
            "kPa"
        } else {
            "MPa at 1 MPa modulus"
        }
    );
    let _ = write!(
        out,
        r#"<text x="10" y="32">Fz {:.3}, Fx {:.3}, Fy {:.3}{}; λ {:.2e}, misfit {:.1} µm</text>"#,
        force[2],
        force[0],
        force[1],
        if calibrated { " N" } else { " (nominal)" },
        m.lambda,
        m.misfit_mm * 1e3
    );
    let _ = write!(
        out,
        r##"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="#999"/>"##,
        x(a[0]),
        y(a[1]),
        (b[0] - a[0]) * px_per_mm,
        (b[1] - a[1]) * px_per_mm
    );
    let side = m.cell_mm * px_per_mm;
    for (c, p) in m.cells_mm.iter().zip(&pz) {
        let v = (p / pmax).clamp(-1.0, 1.0);
        let (r, g, bl) = if v >= 0.0 {
            (255.0, 255.0 * (1.0 - v), 255.0 * (1.0 - v))
        } else {
            (255.0 * (1.0 + v), 255.0 * (1.0 + v), 255.0)
        };
        let _ = write!(
            out,
            r#"<rect x="{:.1}" y="{:.1}" width="{side:.1}" height="{side:.1}" fill="rgb({r:.0},{g:.0},{bl:.0})"/>"#,
            x(c[0]) - side / 2.0,
            y(c[1]) - side / 2.0
        );
    }
    for (c, t) in m.cells_mm.iter().zip(&m.traction) {
        let v = [t[0] * gains[0] * unit / tmax, t[1] * gains[1] * unit / tmax];
        let len = side * 1.5;
        let _ = write!(
            out,
            r##"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="#1f3b73" stroke-width="1.2"/>"##,
            x(c[0]),
            y(c[1]),
            x(c[0]) + v[0] * len,
            y(c[1]) + v[1] * len
        );
    }
    out.push_str("</svg>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use analysis::force_sensor::ridge::ChannelFit;
    use analysis::force_sensor::{TRACTION_FEATURES, TRACTION_FEATURES_ROUND};

    fn channel(weights: Vec<f64>) -> ChannelFit {
        let p = weights.len();
        ChannelFit {
            weights,
            bias: 0.3,
            lambda: 0.0,
            sigma: 0.1,
            inv_gram: vec![0.0; p * p],
            dof: p as f64,
        }
    }

    /// The picture's Fz gain is the model's own: moving the map's F̃_z by δ (and with it
    /// the elongation term, F̃_z·e) moves the reading by δ times the gain, for a round and
    /// an elongated contact, with and without the term.
    #[test]
    fn the_pictures_fz_gain_is_the_models_derivative() {
        let names: Vec<String> = TRACTION_FEATURES.iter().map(|f| f.to_string()).collect();
        let model = LinearModel {
            mean: vec![0.01, -0.02, 0.5, 3.0, 0.2],
            scale: vec![0.2, 0.3, 1.7, 9.0, 0.6],
            samples: 100,
            channels: vec![
                channel(vec![0.9, 0.0, 0.0, 0.0, 0.0]),
                channel(vec![0.0, 0.8, 0.0, 0.0, 0.0]),
                channel(vec![0.0, 0.0, 4.1, 0.0, -1.3]),
                channel(vec![0.0, 0.0, 0.0, 2.2, 0.0]),
            ],
        };
        let (gains, g_e, term) = calibrated_gains(&model, &names);
        assert!(term);
        // A strip 20 × 4 (moments w²/12, h²/12): e = 0.96; a disc: e = 0.
        let strip = super::super::history::Region {
            centroid_px: [320.0, 240.0],
            radius_px: 5.0,
            second_moments_px2: Some([400.0 / 12.0, 16.0 / 12.0, 0.0]),
        };
        let disc = super::super::history::Region::disc([320.0, 240.0], 5.0);
        for (region, e) in [(Some(&strip), 0.96), (Some(&disc), 0.0), (None, 0.0)] {
            let at = |fz: f64| {
                let f = [0.02, 0.01, fz, 2.0, fz * e];
                model.predict(&f).0[2]
            };
            let (fz, d) = (1.4, 0.05);
            let want = (at(fz + d) - at(fz)) / d;
            let got = fz_gain(gains, g_e, region);
            assert!((got - want).abs() < 1e-9, "e {e}: {got} vs {want}");
        }
        assert!((gains[2] - 4.1 / 1.7).abs() < 1e-12);
        assert!((g_e + 1.3 / 0.6).abs() < 1e-12);
        // A round sensor's file has no term: its gain is the Fz weight alone.
        let round: Vec<String> = TRACTION_FEATURES_ROUND
            .iter()
            .map(|f| f.to_string())
            .collect();
        let (g4, g_e4, term4) = calibrated_gains(&model, &round);
        assert!(!term4);
        assert_eq!(g_e4, 0.0);
        assert_eq!(fz_gain(g4, g_e4, Some(&strip)), g4[2]);
    }
}
