//! Reading the wrench from the field with a sensor file: per frame of a run (or of a
//! `markers.csv` from `gelrig track`), Fx, Fy, Fz, Tz and a standard uncertainty per channel
//! (the calibration's residual scale, widened where the field is unlike the calibration's),
//! written as `wrench.csv`.

use std::collections::BTreeMap;
use std::path::Path;

use super::{RunFrame, SensorError, SensorFile, unfit};
use crate::run_data::MarkerRow;

pub use rundir::write::rows::WrenchRow;

/// The wrench of every frame of `frames`, whose reference markers are frame 0's; `origin`
/// names the recording in errors.
pub fn wrench_of_frames(
    sensor: &SensorFile,
    frames: &[RunFrame],
    origin: &Path,
) -> Result<Vec<WrenchRow>, SensorError> {
    let Some(first) = frames.first() else {
        return Err(unfit(
            origin,
            "no tracked frames",
            "track the recording first (gelrig track), with its no-contact reference as frame 0",
        ));
    };
    let reader = super::reader::Reader::new(sensor);
    let map = reader
        .layout
        .match_markers(&first.field.reference_px)
        .map_err(|source| SensorError::Model {
            path: origin.to_path_buf(),
            source,
        })?;
    // The memory needs every frame's time; a recording without them reads the field alone.
    let mut history = super::history::LoadHistory::new(
        reader
            .memory()
            .filter(|_| frames.iter().skip(1).all(|f| f.t_ns > 0)),
        reader.fz_range_n(),
        frames.iter().any(|f| f.contact.is_some()),
    );
    Ok(frames
        .iter()
        .map(|f| {
            let region = history.region(&f.field, f.contact);
            let reading = reader.read(&f.field, region, &map);
            let share = reading.measured_share;
            let w = reader.wrench(&reading, region, &mut history, f.t_ns);
            let (v, sd) = (&w.value, &w.sd);
            let at = |x: &[f64], i: usize| x.get(i).copied().unwrap_or(f64::NAN);
            WrenchRow {
                frame: f.frame,
                t_ns: (f.t_ns > 0 || f.frame == 0).then_some(f.t_ns),
                step: f.step,
                fx_n: at(v, 0),
                fy_n: at(v, 1),
                fz_n: at(v, 2),
                tz_nmm: at(v, 3),
                fx_sd_n: at(sd, 0),
                fy_sd_n: at(sd, 1),
                fz_sd_n: at(sd, 2),
                tz_sd_nmm: at(sd, 3),
                measured_share: share,
                outside_calibration: w.judgement.reasons(),
                contact_in_view: w.judgement.in_view,
            }
        })
        .collect())
}

/// The wrench of every frame of a run directory (tracked first if it has no markers.csv).
pub fn read_wrench(sensor: &SensorFile, run_dir: &Path) -> Result<Vec<WrenchRow>, SensorError> {
    let data = crate::run_data::read_run(run_dir)?;
    wrench_of_frames(sensor, &super::run_frames(&data), run_dir)
}

/// The wrench of every frame of a `markers.csv` (frame 0 the reference), with frame times
/// and steps where known ([`super::frame_times`]).
pub fn wrench_of_markers(
    sensor: &SensorFile,
    markers_csv: &Path,
    times: &BTreeMap<u64, (u64, u32)>,
) -> Result<Vec<WrenchRow>, SensorError> {
    wrench_of_frames(sensor, &frames_of_markers(markers_csv, times)?, markers_csv)
}

/// The frames of a `markers.csv` (frame 0 the reference) with the contact regions `gelrig
/// track` wrote beside it (`contact.csv`) and frame times and steps where known.
pub fn frames_of_markers(
    markers_csv: &Path,
    times: &BTreeMap<u64, (u64, u32)>,
) -> Result<Vec<RunFrame>, SensorError> {
    let rows: Vec<MarkerRow> = crate::run_data::read_csv(markers_csv)?;
    let contact_csv = markers_csv.with_file_name(rundir::names::CONTACT);
    let contact: Vec<crate::run_data::ContactRow> = if contact_csv.is_file() {
        crate::run_data::read_csv(&contact_csv)?
    } else {
        Vec::new()
    };
    let mut by_frame: BTreeMap<u64, Vec<MarkerRow>> = BTreeMap::new();
    for r in rows {
        by_frame.entry(r.frame).or_default().push(r);
    }
    Ok(by_frame
        .iter()
        .map(|(&frame, rows)| RunFrame {
            frame,
            t_ns: times.get(&frame).map_or(0, |t| t.0),
            step: times.get(&frame).map_or(0, |t| t.1),
            contact: super::contact_of(&contact, frame),
            field: crate::run_data::field_of_rows(rows),
        })
        .collect())
}

/// Writes `rows` as CSV to `path`.
pub fn write_wrench_csv(rows: &[WrenchRow], path: &Path) -> Result<(), SensorError> {
    let err = |e: String| SensorError::Write {
        path: path.to_path_buf(),
        detail: e,
    };
    let mut w = csv::Writer::from_path(path).map_err(|e| err(e.to_string()))?;
    for r in rows {
        w.serialize(r).map_err(|e| err(e.to_string()))?;
    }
    w.flush().map_err(|e| err(e.to_string()))
}
