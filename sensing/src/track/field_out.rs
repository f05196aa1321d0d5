//! The field folder of `gelrig track --field`: pictures and the field's decomposition per
//! frame.

use std::fs::{self, File};
use std::path::{Path, PathBuf};

use serde::Serialize;
use tracking::Pipeline;
use tracking::field::decompose::{self, ProfileBin};
use tracking::field::picture::{self, Quiver};
use tracking::field::{DenseGrid, Interpolator, MarkerField};

use super::{TrackFailure, r4, write_err};

/// One row of `decomposition.csv` (NaN where a representative does not exist).
#[derive(Debug, Serialize)]
struct DecompositionRow {
    frame: u64,
    measured: usize,
    median_disp_px: f64,
    max_disp_px: f64,
    mean_dx_px: f64,
    mean_dy_px: f64,
    radiating_x_px: f64,
    radiating_y_px: f64,
    shear_direction_deg: f64,
    rotation_deg: f64,
    rotation_x_px: f64,
    rotation_y_px: f64,
}

#[derive(Debug, Serialize)]
struct ProfileRow {
    frame: u64,
    at_px: f64,
    mean_px: f64,
    spread_px: f64,
    count: usize,
}

/// Field outputs of one tracking run.
pub(super) struct FieldWriter {
    dir: PathBuf,
    interpolator: Interpolator,
    quiver: Quiver,
    full_scale_px: f64,
    width: usize,
    height: usize,
    decomposition: csv::Writer<File>,
    radial: csv::Writer<File>,
    central: csv::Writer<File>,
}

impl FieldWriter {
    pub(super) fn new(dir: &Path, pipeline: &Pipeline, magnify: f64) -> Result<Self, TrackFailure> {
        fs::create_dir_all(dir).map_err(|e| write_err(dir)(e.to_string()))?;
        let r = pipeline.reference();
        let (w, h) = (r.width(), r.height());
        let csv_at = |name: &str| {
            let p = dir.join(name);
            csv::Writer::from_path(&p).map_err(|e| write_err(&p)(e.to_string()))
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            interpolator: Interpolator::new(
                pipeline.tracker().reference_px(),
                DenseGrid::over_frame(w, h, 1.0),
            ),
            quiver: Quiver {
                frame_px: (w, h),
                zoom: 2.0,
                magnify,
                spacing_px: r.spacing_px(),
            },
            // Full brightness at half a spacing: the colours of one run compare across frames.
            full_scale_px: 0.5 * r.spacing_px(),
            width: w,
            height: h,
            decomposition: csv_at("decomposition.csv")?,
            radial: csv_at("radial_profile.csv")?,
            central: csv_at("central_line.csv")?,
        })
    }

    pub(super) fn frame(&mut self, frame: u64, pipeline: &Pipeline) -> Result<(), TrackFailure> {
        let tracker = pipeline.tracker();
        let field = MarkerField::interior_from_tracker(tracker);
        let outline = pipeline.contact().map(|c| c.outline_px.as_slice());
        let dense = self.interpolator.interpolate(&field);
        let colours = picture::colour_image(&dense, self.full_scale_px);
        let (g, w, h) = (dense.grid, self.width, self.height);
        debug_assert_eq!((g.nx, g.ny), (w, h));
        let png = self.dir.join(format!("field_{frame:06}.png"));
        image::save_buffer(&png, &colours, w as u32, h as u32, image::ColorType::Rgb8)
            .map_err(|e| write_err(&png)(e.to_string()))?;
        let zoom = self.quiver.zoom as usize;
        let background = picture::upscale(&colours, w, h, zoom);
        let (qw, qh, quiver) =
            picture::quiver_rgb(&field, &self.quiver, Some(&background), outline)
                .map_err(|e| write_err(&self.dir)(e.to_string()))?;
        let qpng = self.dir.join(format!("quiver_{frame:06}.png"));
        image::save_buffer(&qpng, &quiver, qw, qh, image::ColorType::Rgb8)
            .map_err(|e| write_err(&qpng)(e.to_string()))?;
        let svg = picture::quiver_svg(&field, &self.quiver, outline)
            .map_err(|e| write_err(&self.dir)(e.to_string()))?;
        let qsvg = self.dir.join(format!("quiver_{frame:06}.svg"));
        fs::write(&qsvg, svg).map_err(|e| write_err(&qsvg)(e.to_string()))?;

        let sp = pipeline.reference().spacing_px();
        let mags: Vec<f64> = field
            .measured_ids()
            .map(|i| field.displacement_px[i][0].hypot(field.displacement_px[i][1]))
            .collect();
        let centre = decompose::radiating_centre(&field);
        let shear = decompose::shear(&field, None, 0.5 * sp, 0.5 * sp);
        let rotation = decompose::rotation(&field, None, 0.0);
        let nan2 = [f64::NAN; 2];
        let row = DecompositionRow {
            frame,
            measured: mags.len(),
            median_disp_px: r4(decompose::median_magnitude(&field).unwrap_or(f64::NAN)),
            max_disp_px: r4(mags.iter().copied().fold(0.0, f64::max)),
            mean_dx_px: r4(shear.as_ref().map(|s| s.mean_px[0]).unwrap_or(0.0)),
            mean_dy_px: r4(shear.as_ref().map(|s| s.mean_px[1]).unwrap_or(0.0)),
            radiating_x_px: r4(centre.unwrap_or(nan2)[0]),
            radiating_y_px: r4(centre.unwrap_or(nan2)[1]),
            shear_direction_deg: r4(shear
                .as_ref()
                .map(|s| s.direction_rad.to_degrees())
                .unwrap_or(f64::NAN)),
            rotation_deg: r4(rotation
                .map(|r| r.angle_rad.to_degrees())
                .unwrap_or(f64::NAN)),
            rotation_x_px: r4(rotation.and_then(|r| r.centre_px).unwrap_or(nan2)[0]),
            rotation_y_px: r4(rotation.and_then(|r| r.centre_px).unwrap_or(nan2)[1]),
        };
        let path = self.dir.join("decomposition.csv");
        self.decomposition
            .serialize(&row)
            .map_err(|e| write_err(&path)(e.to_string()))?;
        let profile_rows = |bins: &[ProfileBin]| {
            bins.iter()
                .map(|b| ProfileRow {
                    frame,
                    at_px: r4(b.at_px),
                    mean_px: r4(b.mean_px),
                    spread_px: r4(b.spread_px),
                    count: b.count,
                })
                .collect::<Vec<_>>()
        };
        if let Some(c) = centre {
            let path = self.dir.join("radial_profile.csv");
            for r in profile_rows(&decompose::radial_profile(&field, c, 0.5 * sp)) {
                self.radial
                    .serialize(r)
                    .map_err(|e| write_err(&path)(e.to_string()))?;
            }
        }
        if let Some(s) = &shear {
            let path = self.dir.join("central_line.csv");
            for r in profile_rows(&s.central_line) {
                self.central
                    .serialize(r)
                    .map_err(|e| write_err(&path)(e.to_string()))?;
            }
        }
        for (w, name) in [
            (&mut self.decomposition, "decomposition.csv"),
            (&mut self.radial, "radial_profile.csv"),
            (&mut self.central, "central_line.csv"),
        ] {
            w.flush()
                .map_err(|e| write_err(&self.dir.join(name))(e.to_string()))?;
        }
        Ok(())
    }
}
