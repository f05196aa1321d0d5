//! gelrig's public API: what the `gelrig` command, the Python package and any other program
//! use to load and plan a protocol, run it and hear its events, read a run directory's
//! tables, track frames from pixels in memory, read a calibrated GelSight force sensor from a
//! frame, and render a frame of the simulated bench for a contact given by hand.
//!
//! Each module below gathers one of those jobs from the crates that do it (ARCHITECTURE.md
//! names them); the crates themselves are re-exported at the end for anything further.
//!
//! # A protocol, checked and planned
//!
//! Loading reads the protocol and its rig, checks every value (each problem located at its
//! file, line and column, with the fix) and plans it once; the plan travels with it.
//!
//! ```
//! use gelrig::protocol;
//!
//! let path = protocol::shipped::resolve("box-normal-flat".as_ref()).0;
//! let loaded = protocol::load(&path, None).expect("a shipped protocol loads");
//! let plan = &loaded.plan;
//! assert_eq!(plan.steps.len(), 20);
//! // An hour on a real bench: twenty steps, each settled for three minutes.
//! assert!(plan.duration_s.min > 3600.0);
//!
//! // A protocol edited from the command line is checked the same way.
//! let edit = protocol::Overrides { set: vec!["indenter.diameter=1000mm".into()], ..Default::default() };
//! let refused = protocol::load_with_overrides(&path, None, &Default::default(), &edit);
//! assert!(refused.is_err());
//! ```
//!
//! # A run, and its events as it goes
//!
//! [`run::Launch`] says once what to run, where and how; on a simulated rig the run goes in
//! virtual time (an hour of settling in seconds), deterministic for its seed.
//!
//! ```
//! use std::sync::{Arc, Mutex};
//! use gelrig::{protocol, run};
//!
//! let path = protocol::shipped::resolve("box-normal-flat".as_ref()).0;
//! let loaded = protocol::load(&path, None).unwrap();
//! let runs = tempfile::tempdir().unwrap();
//! let steps_done = Arc::new(Mutex::new(0));
//! let counter = steps_done.clone();
//! let outcome = run::Launch::new(&loaded)
//!     .out(runs.path())
//!     .seed(1)
//!     .on_event(Arc::new(move |event: &run::Event| {
//!         if let run::Event::StepDone { .. } = event {
//!             *counter.lock().unwrap() += 1;
//!         }
//!     }))
//!     .run_blocking(run::Cancel::new())
//!     .expect("the run directory is written");
//! assert_eq!(outcome.status, gelrig::runs::Status::Completed);
//! assert_eq!(*steps_done.lock().unwrap(), 20);
//!
//! // Its tables, read back.
//! let data = gelrig::runs::read(&outcome.dir).unwrap();
//! assert_eq!(data.steps.len(), 20);
//! assert!(data.force.len() > 1000);
//! ```
//!
//! # Tracking frames held in memory
//!
//! A [`track::Pipeline`] measures a reference frame of the untouched gel, then follows every
//! marker through the frames it is given (RGB bytes, row-major). Here the frames come from
//! the simulated bench's camera for a contact given by hand ([`sim::ContactCamera`]), so the
//! true marker positions are known.
//!
//! ```
//! use gelrig::{protocol, sim, track};
//!
//! let path = protocol::shipped::resolve("box-normal-flat".as_ref()).0;
//! let loaded = protocol::load(&path, None).unwrap();
//! let spec = sim::plant_spec(&loaded.protocol, &loaded.compiled).unwrap();
//! let mut camera = sim::ContactCamera::new(&spec, 320, 240).unwrap();
//!
//! let rest = camera.at_rest(0);
//! fn view(f: &sim::ContactFrame) -> track::RgbView<'_> {
//!     track::RgbView::new(f.width as usize, f.height as usize, &f.rgb).expect("its own size")
//! }
//! let mut pipeline =
//!     track::Pipeline::new(view(&rest), &track::TrackParams::default(), track::Method::Centroid)
//!         .unwrap();
//!
//! let pressed = camera
//!     .frame(&sim::ContactPose { depth_mm: 0.5, ..Default::default() }, 1)
//!     .unwrap();
//! pipeline.track(view(&pressed)).unwrap();
//! let tracker = pipeline.tracker();
//! let moved = (0..tracker.len())
//!     .filter(|&k| tracker.states()[k].is_measured())
//!     .map(|k| tracker.displacement_px(k))
//!     .filter(|d| d[0].hypot(d[1]) > 0.3)
//!     .count();
//! assert!(moved > 10, "a 0.5 mm press moves the markers around the punch: {moved}");
//! ```
//!
//! # The GelSight's force from a frame
//!
//! A sensor file written by `gelrig calibrate` (or [`force::calibrate`]) reads Fx, Fy, Fz
//! and Tz from the tracked field, each with its standard uncertainty and a judgement of
//! whether the frame lies inside what was calibrated. [`force::LiveReader`] does it frame by
//! frame; `gelrig track --sensor` does it for a recorded run.
//!
//! ```no_run
//! use gelrig::{force, track};
//!
//! # fn frames() -> Vec<(Vec<u8>, u64)> { Vec::new() }
//! let sensor = force::SensorFile::read("my-gelsight.yaml".as_ref()).unwrap();
//! let mut reader = force::LiveReader::new(&sensor);
//! let mut pipeline: Option<track::Pipeline> = None;
//! for (rgb, t_ns) in frames() {
//!     let view = track::RgbView::new(640, 480, &rgb).unwrap();
//!     let Some(p) = pipeline.as_mut() else {
//!         let params = track::TrackParams::default();
//!         pipeline = Some(track::Pipeline::new(view, &params, track::Method::Centroid).unwrap());
//!         continue;
//!     };
//!     p.track(view).unwrap();
//!     let wrench = reader.read(p, t_ns).unwrap();
//!     println!("Fz {:.2} ± {:.2} N", wrench.value[2], wrench.sd[2]);
//! }
//! ```
//!
//! The test `tests/e2e/api.rs` runs the same code on a sensor it calibrates from dry runs
//! (calibration takes tens of seconds: too long for an example here).
//!
//! # Height maps from the lights
//!
//! A shape sensor calibrated on ball presses (`gelrig shape calibrate` does this from files),
//! then a frame read into a height map in mm. Here the presses are drawn by a colour change
//! linear in the gel's slope, as a GelSight's lights give it.
//!
//! ```
//! use gelrig::shape::{Circle, Depth, Press, Rgb, SlopeModel, calibrate};
//!
//! let (w, h, ball_px, mm_per_px) = (160usize, 120usize, 40.0, 0.1);
//! let background = vec![120u8; w * h * 3];
//! let press = |c: &Circle| -> Vec<u8> {
//!     let mut px = background.clone();
//!     for i in 0..w * h {
//!         let (x, y) = ((i % w) as f64 - c.x_px, (i / w) as f64 - c.y_px);
//!         if x * x + y * y < c.radius_px * c.radius_px {
//!             let s = (ball_px * ball_px - x * x - y * y).sqrt();
//!             let (gx, gy) = (-x / s, -y / s);
//!             for (k, d) in [60.0 * gy, -90.0 * gx, 40.0 * gx - 50.0 * gy].iter().enumerate() {
//!                 px[3 * i + k] = (120.0 + d).round() as u8;
//!             }
//!         }
//!     }
//!     px
//! };
//! let circles: Vec<Circle> = [(40.0, 30.0), (120.0, 30.0), (80.0, 60.0), (40.0, 90.0), (120.0, 90.0)]
//!     .iter()
//!     .map(|&(x_px, y_px)| Circle { x_px, y_px, radius_px: 15.0 })
//!     .collect();
//! let frames: Vec<Vec<u8>> = circles.iter().map(|c| press(c)).collect();
//! let bg = Rgb::new(w, h, &background).unwrap();
//! let presses: Vec<Press<'_>> = frames
//!     .iter()
//!     .zip(&circles)
//!     .map(|(f, c)| Press { name: "press".into(), frame: Rgb::new(w, h, f).unwrap(), circle: *c })
//!     .collect();
//! let calibration = calibrate(bg, &presses, ball_px, mm_per_px).unwrap();
//! let map = SlopeModel::LocalLinear(calibration.local_linear).prepare(w, h).unwrap();
//! let mut depth = Depth::new(map, bg, mm_per_px).unwrap();
//! let height_mm = depth.height(Rgb::new(w, h, &frames[2]).unwrap()).unwrap();
//! // The deepest point sits over the ball's centre, about its cap's depth below the gel.
//! let cap_mm = (ball_px - (ball_px * ball_px - 15.0f64 * 15.0).sqrt()) * mm_per_px;
//! assert!(f64::from(height_mm[60 * w + 80]) < -0.8 * cap_mm);
//! assert!(depth.stats().max_depth_mm > 0.8 * cap_mm);
//! ```

pub mod cli;
pub mod view;

/// Protocols: load one with its rig, check it, plan it; shipped protocols by name; the
/// schema (for editors) and rig files on their own.
pub mod protocol {
    pub use experiments::load::{Loaded, Overrides, load, load_with, load_with_overrides};
    pub use experiments::plan::{Plan, PlannedStep, Range};
    pub use experiments::protocol::compile::Budget;
    pub use experiments::protocol::{load_rig, schema, shipped};
    pub use experiments::{Diagnostic, Severity};
    pub use rig::config::RigConfig;
}

/// Running a loaded protocol: the launch, its events, how it ended, and resuming.
pub mod run {
    pub use rig::ClockMode;
    pub use runner::progress::ProgressMode;
    pub use runner::{
        Cancel, Event, GELSIGHT_SENSOR_FILE, Launch, Observer, Resume, RunOutcome, clock_for,
        time_scale,
    };
}

/// Run directories: every file's name, the tables read back, the listing of a folder of runs
/// and the exports (MCAP, Parquet).
pub mod runs {
    pub use rundir::listing;
    pub use rundir::manifest::{Manifest, Status, is_locked, read_manifest};
    pub use rundir::{export, names};
    pub use sensing::run_data::{
        ForceRow, FrameRow, RunData, RunDirError, StepRow, TactileCsvRow, read_csv, read_optional,
    };

    /// Reads the tables of the run in `dir`: steps, force, frames, and the markers and
    /// contact once tracked.
    pub fn read(dir: &std::path::Path) -> Result<RunData, RunDirError> {
        sensing::run_data::read_run_tables(dir)
    }
}

/// Marker tracking on frames held in memory, and the contact region; [`track::recorded`]
/// tracks the frames of a run directory or an image folder into `markers.csv`.
pub mod track {
    pub use tracking::field::MarkerField;
    pub use tracking::{
        ContactParams, ContactRegion, MarkerState, Method, Pipeline, RgbView, TrackParams, Tracker,
    };

    /// Tracking recorded frames (`gelrig track`): a run's or a folder's PNGs into
    /// `markers.csv`, `contact.csv`, `depth.csv` and field pictures.
    pub mod recorded {
        pub use sensing::track::{
            Input, Options, ShapeReading, Summary, TrackFailure, detect_only, load_rgb,
            step_last_frames, track,
        };
    }
}

/// The GelSight as a force sensor: calibration, reading frame by frame, and reading a
/// tracked run (`wrench.csv`, traction maps).
pub mod force {
    pub use sensing::sensor::calibrate::{CalibrateOptions, Method};
    pub use sensing::sensor::live::LiveReader;
    pub use sensing::sensor::reader::Wrench;
    pub use sensing::sensor::{
        SensorError, SensorFile, WrenchRow, calibrate, envelope, file, frame_times,
        frames_of_markers, maps, wrench_of_markers, write_wrench_csv,
    };
}

/// The user's own gel: a material fitted to a bench's runs (`gelrig fit-material`).
/// Shape from the GelSight's light (issue 50): a ball calibration into `shape.yaml`, and
/// frames into height maps.
pub mod shape {
    pub use ::shape::ball::{BallScore, Circle};
    pub use ::shape::{
        Calibration, Depth, DepthStats, HeldOut, ModelKind, Press, Rgb, SlopeModel, calibrate,
        find_circle,
    };
    pub use sensing::shape::file::{ModelFigures, UsedPress};
    pub use sensing::shape::{
        CirclesFrom, ShapeFile, ShapeFileError, ShapeRow, calibrate_dir, read_presses,
        write_height_maps,
    };
}

/// Campaigns: a protocol swept over its parameters (`gelrig sweep`): the sweep file, its
/// points, shards of a job array, each point's outcome and the Slurm scripts.
pub mod campaign {
    pub use ::campaign::{
        Campaign, CampaignError, Design, Outcome, Params, Point, Range, Shard, Sweep, points,
        slurm, write_atomic,
    };
}

pub mod material {
    pub use sensing::material::{FitError, MaterialFile, MaterialFileError, fit};
}

/// Reports on runs, and comparisons of several.
pub mod reports {
    pub use report::{ReportError, Written, compare, headline, report, report_with_sensor};
}

/// The simulated bench: frames for a contact given by hand, the bench a protocol
/// describes, and its devices' twins on real transports (`gelrig sim serve`).
pub mod sim {
    pub use experiments::protocol::plant_spec;
    pub use simbench::bench;
    pub use simbench::{
        ContactCamera, ContactFrame, ContactPose, Fidelity, MarkerLayout, PlantSpec, Quality,
        quality_for,
    };
}

/// The live view's page and server (`--live`, `gelrig view`).
pub mod live {
    pub use liveview::{Board, Library, Server};
}

pub use experiments;
pub use report;
pub use runner;
pub use sensing;
