//! The rows of the run directory's CSV files.

use records::Wrench;
use serde::{Deserialize, Serialize};

/// One row of `steps.csv`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepRow {
    /// Step number.
    pub step: u32,
    /// Trial.
    pub trial: u32,
    /// Label.
    pub label: String,
    /// load, unload, move, hold, capture, disturb.
    pub phase: String,
    /// Axis moved, or empty.
    pub axis: String,
    /// Target relative to the axis origin, axis unit (empty without a move).
    pub target: Option<f64>,
    /// Position relative to the axis origin at the end of the step.
    pub position: Option<f64>,
    /// mm or deg.
    pub unit: String,
    /// Quasistatic force and torque: the window mean (adaptive settling: F∞ for the settled
    /// channel).
    pub fx_n: Option<f64>,
    /// See `fx_n`.
    pub fy_n: Option<f64>,
    /// See `fx_n`.
    pub fz_n: Option<f64>,
    /// See `fx_n`.
    pub tx_nmm: Option<f64>,
    /// See `fx_n`.
    pub ty_nmm: Option<f64>,
    /// See `fx_n`.
    pub tz_nmm: Option<f64>,
    /// Time waited after the move, s.
    pub settle_s: f64,
    /// fixed, converged, timeout or none.
    pub settle_verdict: String,
    /// Averaging window, s.
    pub force_window_s: f64,
    /// Samples in the window.
    pub window_samples: u32,
    /// Standard deviation of the signal along the axis over the window.
    pub window_std: Option<f64>,
    /// Whether any sample in the step was saturated.
    pub saturated: bool,
    /// Frames captured.
    pub frames: u32,
    /// Absolute position at the end.
    pub position_abs: Option<f64>,
    /// Step start, ns.
    pub t_start_ns: u64,
    /// End of the settle, which is the end of the force window, ns.
    pub settle_end_ns: u64,
    /// Step end (after any frames), ns.
    pub t_end_ns: u64,
    /// Adaptive settling: the equilibrium value of the settled channel, fitted to its
    /// relaxation; the step's quasistatic value (its column above holds it too).
    #[serde(default)]
    pub f_inf: Option<f64>,
    /// Standard uncertainty of `f_inf`.
    #[serde(default)]
    pub f_inf_sigma: Option<f64>,
    /// Adaptive settling: the settled channel's window mean (the thesis's quasistatic value,
    /// kept beside F∞).
    #[serde(default)]
    pub window_mean: Option<f64>,
}

impl StepRow {
    pub(super) fn example() -> Self {
        Self {
            step: 0,
            trial: 0,
            label: String::new(),
            phase: String::new(),
            axis: String::new(),
            target: None,
            position: None,
            unit: String::new(),
            fx_n: None,
            fy_n: None,
            fz_n: None,
            tx_nmm: None,
            ty_nmm: None,
            tz_nmm: None,
            settle_s: 0.0,
            settle_verdict: String::new(),
            force_window_s: 0.0,
            window_samples: 0,
            window_std: None,
            saturated: false,
            frames: 0,
            position_abs: None,
            t_start_ns: 0,
            settle_end_ns: 0,
            t_end_ns: 0,
            f_inf: None,
            f_inf_sigma: None,
            window_mean: None,
        }
    }
}

pub(super) fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

#[derive(Serialize, Default)]
pub(super) struct ForceRow {
    pub(super) t_ns: u64,
    pub(super) step: u32,
    pub(super) trial: u32,
    pub(super) fx_n: f64,
    pub(super) fy_n: f64,
    pub(super) fz_n: f64,
    pub(super) tx_nmm: f64,
    pub(super) ty_nmm: f64,
    pub(super) tz_nmm: f64,
    pub(super) ft_seq: u64,
    pub(super) status: u32,
}

#[derive(Serialize, Default)]
pub(super) struct AxesRow<'a> {
    pub(super) t_ns: u64,
    pub(super) axis: &'a str,
    pub(super) target: Option<f64>,
    pub(super) position: f64,
}

#[derive(Serialize)]
pub(super) struct MarkerTruthRow {
    pub(super) frame: u64,
    pub(super) id: usize,
    pub(super) x_px: f64,
    pub(super) y_px: f64,
}

/// `sim_frames.csv`: the simulator's contact under one frame, and its maps' file.
#[derive(Serialize)]
pub(super) struct SimFrameRow<'a> {
    pub(super) frame: u64,
    pub(super) maps: &'a str,
    pub(super) depth_mm: f64,
    pub(super) shear_n: f64,
    pub(super) torque_nmm: f64,
    pub(super) centre_x_mm: f64,
    pub(super) centre_y_mm: f64,
    pub(super) rotation_rad: f64,
    pub(super) fz_n: f64,
    pub(super) fx_n: f64,
    pub(super) fy_n: f64,
    pub(super) contact_area_mm2: f64,
    pub(super) cell_mm: f64,
}

#[derive(Serialize, Default)]
pub(super) struct SimStepRow {
    pub(super) step: u32,
    pub(super) trial: u32,
    pub(super) depth_mm: f64,
    pub(super) fx_n: f64,
    pub(super) fy_n: f64,
    pub(super) fz_n: f64,
    pub(super) tz_nmm: f64,
    pub(super) fx_eq_n: f64,
    pub(super) fz_eq_n: f64,
    pub(super) tz_eq_nmm: f64,
    pub(super) contact_radius_mm: f64,
    pub(super) shear_stick_fraction: Option<f64>,
    pub(super) twist_stick_fraction: Option<f64>,
    pub(super) shear_slips: u32,
    pub(super) twist_slips: u32,
    pub(super) object_slips: u32,
}

#[derive(Serialize, Default)]
pub(super) struct FrameRow<'a> {
    pub(super) frame: u64,
    pub(super) t_ns: u64,
    pub(super) step: u32,
    pub(super) trial: u32,
    pub(super) file: &'a str,
    pub(super) seq: u64,
    pub(super) fx_n: Option<f64>,
    pub(super) fy_n: Option<f64>,
    pub(super) fz_n: Option<f64>,
    pub(super) tx_nmm: Option<f64>,
    pub(super) ty_nmm: Option<f64>,
    pub(super) tz_nmm: Option<f64>,
    pub(super) fz_sd_n: Option<f64>,
    pub(super) force_samples: Option<u32>,
    pub(super) sim_t_ns: Option<u64>,
}

/// The force a frame saw: the tared wrench averaged over the force samples inside its
/// exposure (`frames.csv`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameForce {
    /// Mean tared wrench over the samples inside the exposure; with none inside, the
    /// wrench interpolated at the exposure midpoint between the samples around it.
    pub wrench: Wrench,
    /// Standard deviation of Fz over those samples, N (`None` for fewer than two).
    pub fz_sd_n: Option<f64>,
    /// Samples inside the exposure (0: interpolated).
    pub samples: u32,
}

/// One row of `tactile.csv`: a frame's live tactile state in a grasp (thesis §6.3) and, on
/// a simulated bench, the truth it is scored against.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct TactileRow {
    /// Frame number (as in `frames.csv`).
    pub frame: u64,
    /// Exposure time on the run's timebase, ns.
    pub t_ns: u64,
    /// Step running (0 between steps).
    pub step: u32,
    /// Trial.
    pub trial: u32,
    /// stick, incipient or slip.
    pub state: String,
    /// A pressing field is set (the grip has closed).
    pub gripping: bool,
    /// Share of contact markers following the contact's rigid motion.
    pub stuck_fraction: f64,
    /// Rigid shear of the contact (total − pressing field), px.
    pub shear_x_px: f64,
    /// See `shear_x_px`.
    pub shear_y_px: f64,
    /// Rotation of the contact about the normal, degrees.
    pub rotation_deg: f64,
    /// Rms frame-to-frame change of the field inside the contact, px.
    pub differential_px: f64,
    /// Rms of the total field, px.
    pub total_px: f64,
    /// Markers inside the contact.
    pub contact_markers: u32,
    /// Contact area from the image, mm² (empty without an image scale).
    pub contact_area_mm2: Option<f64>,
    /// Contact area over its value at the end of the grip.
    pub area_ratio: f64,
    /// Tracking and judging this frame took, ms.
    pub ms: f64,
    /// Simulated: fraction of the gel's contact that sticks under the load along the lift.
    pub true_stick_fraction: Option<f64>,
    /// Simulated: fraction that sticks under the torque about the normal.
    pub true_twist_stick_fraction: Option<f64>,
    /// Simulated: the gel side's friction margin along the lift, 1 − |Q| / Q_max.
    pub true_margin: Option<f64>,
    /// Simulated: the gel side's torsional margin, 1 − |M| / M_max.
    pub true_twist_margin: Option<f64>,
    /// Simulated: the object's velocity relative to the pads, mm/s.
    pub true_slip_mm_s: Option<f64>,
    /// Simulated: the object's height above the table, mm.
    pub true_height_mm: Option<f64>,
    /// Simulated: the object slides through the grasp (gross slip).
    pub true_sliding: Option<bool>,
    /// Simulated: the object turns in the grasp (the gel's twist in full slip).
    pub true_rotating: Option<bool>,
    /// Simulated: the object stands on the table.
    pub true_on_table: Option<bool>,
    /// The GelSight's own reading of Fx with `record.gelsight_force`'s sensor file, N.
    pub gelsight_fx_n: Option<f64>,
    /// Its Fy, N.
    pub gelsight_fy_n: Option<f64>,
    /// Its Fz, N.
    pub gelsight_fz_n: Option<f64>,
    /// Its Tz, N·mm.
    pub gelsight_tz_nmm: Option<f64>,
    /// Standard uncertainty of `gelsight_fx_n` (wide where the field is unlike the
    /// calibration's), N.
    pub gelsight_fx_sd_n: Option<f64>,
    /// Of `gelsight_fy_n`, N.
    pub gelsight_fy_sd_n: Option<f64>,
    /// Of `gelsight_fz_n`, N.
    pub gelsight_fz_sd_n: Option<f64>,
    /// Of `gelsight_tz_nmm`, N·mm.
    pub gelsight_tz_sd_nmm: Option<f64>,
}

/// Every reader's view of a table asks only for columns the writer writes: a column renamed
/// or dropped here fails this test, not a report months later.
#[cfg(test)]
mod views {
    use serde::de::{self, Deserialize, Visitor};

    use super::*;
    use crate::read;

    /// The fields a `Deserialize` type asks a deserializer for.
    struct Fields(Vec<&'static str>);

    #[derive(Debug)]
    struct Stop;
    impl std::fmt::Display for Stop {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("stop")
        }
    }
    impl std::error::Error for Stop {}
    impl de::Error for Stop {
        fn custom<T: std::fmt::Display>(_: T) -> Self {
            Stop
        }
    }

    impl<'de> de::Deserializer<'de> for &mut Fields {
        type Error = Stop;
        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Stop> {
            Err(Stop)
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Stop> {
            self.0 = fields.to_vec();
            Err(Stop)
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes
            byte_buf option unit unit_struct newtype_struct seq tuple tuple_struct map enum
            identifier ignored_any
        }
    }

    fn asked<T: for<'de> Deserialize<'de>>() -> Vec<&'static str> {
        let mut f = Fields(Vec::new());
        let _ = T::deserialize(&mut f);
        f.0
    }

    fn header<T: Serialize>(row: &T) -> Vec<String> {
        let mut w = csv::Writer::from_writer(Vec::new());
        w.serialize(row).expect("row");
        let bytes = w.into_inner().expect("flush");
        let text = String::from_utf8(bytes).expect("utf-8");
        text.lines()
            .next()
            .unwrap_or("")
            .split(',')
            .map(str::to_string)
            .collect()
    }

    fn check(table: &str, view: Vec<&'static str>, written: Vec<String>) {
        assert!(!view.is_empty(), "{table}: the view lists no field");
        for f in view {
            assert!(
                written.iter().any(|w| w == f),
                "{table}: readers ask for `{f}`, which the writer does not write ({written:?})"
            );
        }
    }

    #[test]
    fn readers_ask_only_for_columns_the_writer_writes() {
        check(
            "steps.csv",
            asked::<read::StepRow>(),
            header(&StepRow::example()),
        );
        check(
            "force.csv",
            asked::<read::ForceRow>(),
            header(&ForceRow::default()),
        );
        check(
            "sim_steps.csv",
            asked::<read::SimRow>(),
            header(&SimStepRow::default()),
        );
        check(
            "frames.csv",
            asked::<read::FrameRow>(),
            header(&FrameRow::default()),
        );
        check(
            "tactile.csv",
            asked::<read::TactileCsvRow>(),
            header(&TactileRow::default()),
        );
    }

    #[test]
    fn the_check_catches_a_column_the_writer_lacks() {
        #[derive(serde::Deserialize)]
        #[allow(dead_code)]
        struct Renamed {
            t_ns: u64,
            fz_newtons: f64,
        }
        let r = std::panic::catch_unwind(|| {
            check(
                "force.csv",
                asked::<Renamed>(),
                header(&ForceRow::default()),
            )
        });
        assert!(r.is_err());
    }
}

/// One row of `markers.csv`.
#[derive(Debug, Serialize)]
pub struct MarkerRow<'a> {
    /// Frame number (0: the reference).
    pub frame: u64,
    /// The image the frame came from.
    pub file: &'a str,
    /// The marker's identity, fixed for the sequence.
    pub id: usize,
    /// Position, px.
    pub x_px: f64,
    /// Position, px.
    pub y_px: f64,
    /// Displacement from the reference, px.
    pub dx_px: f64,
    /// Displacement from the reference, px.
    pub dy_px: f64,
    /// `tracked`, `border`, `merged`, `predicted`, `out_of_view`, `ambiguous` or `lost`.
    pub state: &'static str,
    /// Confidence in the identity, 0–1 (0 when not measured).
    pub confidence: f64,
}

/// One row of `contact.csv` (empty centroid and mm columns where unknown).
#[derive(Debug, Serialize)]
pub struct ContactRow {
    /// Frame number.
    pub frame: u64,
    /// Area of the region, px² (0 without contact).
    pub area_px2: f64,
    /// Area, mm², where the image scale is known.
    pub area_mm2: Option<f64>,
    /// Centroid, px.
    pub cx_px: Option<f64>,
    /// Centroid, px.
    pub cy_px: Option<f64>,
    /// Equivalent radius, mm.
    pub radius_mm: Option<f64>,
    /// Equivalent radius, px.
    pub radius_px: f64,
    /// Central second moments per unit area, px².
    pub sxx_px2: Option<f64>,
    /// Central second moments per unit area, px².
    pub syy_px2: Option<f64>,
    /// Central second moments per unit area, px².
    pub sxy_px2: Option<f64>,
}

/// One row of `wrench.csv`: a frame's wrench read from the GelSight (`gelrig track
/// --sensor`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WrenchRow {
    /// Frame number (0 = the reference).
    pub frame: u64,
    /// Time on the run's timebase (empty for frames outside a run).
    pub t_ns: Option<u64>,
    /// Step of the run it was taken in (0 outside a run).
    pub step: u32,
    /// Force along the image's x, N.
    pub fx_n: f64,
    /// Force along y, N.
    pub fy_n: f64,
    /// Normal force, N.
    pub fz_n: f64,
    /// Torque about the normal, N·mm.
    pub tz_nmm: f64,
    /// Standard uncertainty of fx_n, N.
    pub fx_sd_n: f64,
    /// Of fy_n, N.
    pub fy_sd_n: f64,
    /// Of fz_n, N.
    pub fz_sd_n: f64,
    /// Of tz_nmm, N·mm.
    pub tz_sd_nmm: f64,
    /// Share of the sensor's markers measured in this frame (the rest filled).
    pub measured_share: f64,
    /// Why the frame is outside the calibration, `;`-separated (`shape`, `size`, `place`,
    /// `view_edge`, `field`, `load`); empty inside it. The uncertainties are widened for
    /// each.
    pub outside_calibration: String,
    /// The share of the contact the view sees (1 where it is whole in view).
    pub contact_in_view: f64,
}
