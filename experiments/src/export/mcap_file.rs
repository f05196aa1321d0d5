//! The MCAP writer of a run directory ([`super`] lists the topics).

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::cdr::Cdr;
use crate::rundir::{ForceRow, RunDirError, read_csv, read_optional};

/// Why a run could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The run directory could not be read.
    #[error(transparent)]
    Run(#[from] RunDirError),
    /// The output could not be written.
    #[error(
        "cannot write {path}: {detail}; fix: check the folder exists, is writable and has room"
    )]
    Write {
        /// The output file.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    /// The file written.
    pub path: PathBuf,
    /// Messages per topic.
    pub messages: BTreeMap<String, usize>,
}

const SEP: &str =
    "================================================================================";

/// `.msg` definitions of the types used, each with its dependencies as ROS 2 bags carry them.
fn definition(main: &str, deps: &[&str]) -> String {
    let mut s = main.trim().to_string();
    for d in deps {
        s.push('\n');
        s.push_str(SEP);
        s.push('\n');
        s.push_str(d.trim());
    }
    s.push('\n');
    s
}

const HEADER: &str = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id";
const TIME: &str = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec";

/// One row of `axes.csv`.
#[derive(Debug, Deserialize)]
struct AxesRow {
    t_ns: u64,
    axis: String,
    position: Option<f64>,
}

/// One row of `frames.csv`.
#[derive(Debug, Deserialize)]
struct FrameFileRow {
    frame: u64,
    t_ns: u64,
    file: String,
}

/// A CSV row as JSON: integers stay integers, numbers numbers, `true`/`false` booleans, an
/// empty cell null, the rest text.
fn json_row(row: &BTreeMap<String, String>) -> serde_json::Map<String, serde_json::Value> {
    row.iter()
        .map(|(k, v)| {
            let value = if v.is_empty() {
                serde_json::Value::Null
            } else if let Ok(i) = v.parse::<i64>() {
                serde_json::Value::from(i)
            } else if let Some(x) = v.parse::<f64>().ok().filter(|x| x.is_finite()) {
                serde_json::Value::from(x)
            } else if v == "true" || v == "false" {
                serde_json::Value::from(v == "true")
            } else {
                serde_json::Value::from(v.clone())
            };
            (k.clone(), value)
        })
        .collect()
}

/// Writes `run_dir` as MCAP to `out`.
pub fn export_mcap(run_dir: &Path, out: &Path) -> Result<Exported, ExportError> {
    if !run_dir.join("run.yaml").is_file() {
        return Err(RunDirError::Missing {
            path: run_dir.join("run.yaml"),
            detail: "not a run directory".into(),
        }
        .into());
    }
    let werr = |e: String| ExportError::Write {
        path: out.to_path_buf(),
        detail: e,
    };
    let file = File::create(out).map_err(|e| werr(e.to_string()))?;
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .library(format!("gelrig {}", env!("CARGO_PKG_VERSION")))
        .compression(None)
        .create(BufWriter::new(file))
        .map_err(|e| werr(e.to_string()))?;
    let m = |e: mcap::McapError| werr(e.to_string());
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let channel = |w: &mut mcap::Writer<BufWriter<File>>,
                   name: &str,
                   def: String,
                   topic: &str|
     -> Result<u16, ExportError> {
        let schema = w.add_schema(name, "ros2msg", def.as_bytes()).map_err(m)?;
        w.add_channel(schema, topic, "cdr", &BTreeMap::new())
            .map_err(m)
    };
    let mut put = |w: &mut mcap::Writer<BufWriter<File>>,
                   ch: u16,
                   topic: &str,
                   t_ns: u64,
                   data: Vec<u8>|
     -> Result<(), ExportError> {
        let n = counts.entry(topic.to_string()).or_default();
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: *n as u32,
                log_time: t_ns,
                publish_time: t_ns,
            },
            &data,
        )
        .map_err(m)?;
        *n += 1;
        Ok(())
    };

    // Force and torque, SI.
    let force: Vec<ForceRow> = read_optional(&run_dir.join("force.csv"))?.unwrap_or_default();
    if !force.is_empty() {
        let def = definition(
            "std_msgs/Header header\nWrench wrench",
            &[
                HEADER,
                TIME,
                "MSG: geometry_msgs/Wrench\nVector3  force\nVector3  torque",
                "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z",
            ],
        );
        let ch = channel(&mut w, "geometry_msgs/msg/WrenchStamped", def, "/force")?;
        for r in &force {
            let mut c = Cdr::new();
            c.header(r.t_ns, "force_sensor")
                .f64(r.fx_n)
                .f64(r.fy_n)
                .f64(r.fz_n)
                .f64(r.tx_nmm / 1000.0)
                .f64(r.ty_nmm / 1000.0)
                .f64(r.tz_nmm / 1000.0);
            put(&mut w, ch, "/force", r.t_ns, c.finish())?;
        }
    }
    // Frames: the PNG bytes as recorded.
    let frames: Vec<FrameFileRow> = read_optional(&run_dir.join("frames.csv"))?.unwrap_or_default();
    if !frames.is_empty() {
        let def = definition(
            "std_msgs/Header header\nstring format\nuint8[] data",
            &[HEADER, TIME],
        );
        let topic = "/camera/image/compressed";
        let ch = channel(&mut w, "sensor_msgs/msg/CompressedImage", def, topic)?;
        for f in &frames {
            let path = run_dir.join(&f.file);
            let bytes = std::fs::read(&path).map_err(|e| RunDirError::Missing {
                path: path.clone(),
                detail: format!("frame {}: {e}", f.frame),
            })?;
            let mut c = Cdr::new();
            c.header(f.t_ns, "camera").string("png").bytes(&bytes);
            put(&mut w, ch, topic, f.t_ns, c.finish())?;
        }
    }
    // Stage positions, SI: m for linear axes, rad for rotary ones.
    let axes: Vec<AxesRow> = read_optional(&run_dir.join("axes.csv"))?.unwrap_or_default();
    if !axes.is_empty() {
        let rotary: Vec<String> = std::fs::read_to_string(run_dir.join("rig.yaml"))
            .ok()
            .and_then(|t| rig::config::RigConfig::from_yaml_str(&t).ok())
            .map(|rig| {
                rig.axes
                    .iter()
                    .filter(|(_, a)| a.unit() == rig::units::AxisUnit::Deg)
                    .map(|(r, _)| r.name().to_string())
                    .collect()
            })
            .unwrap_or_default();
        let def = definition(
            "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort",
            &[HEADER, TIME],
        );
        let ch = channel(&mut w, "sensor_msgs/msg/JointState", def, "/stages")?;
        for r in axes.iter().filter(|r| r.position.is_some()) {
            let p = r.position.unwrap_or(0.0);
            let si = if rotary.contains(&r.axis) {
                p.to_radians()
            } else {
                p / 1000.0
            };
            let mut c = Cdr::new();
            c.header(r.t_ns, "stages")
                .strings(std::slice::from_ref(&r.axis))
                .f64s(&[si])
                .f64s(&[])
                .f64s(&[]);
            put(&mut w, ch, "/stages", r.t_ns, c.finish())?;
        }
    }
    // Steps: each row as JSON at the step's end.
    let steps_path = run_dir.join("steps.csv");
    if steps_path.is_file() {
        let rows: Vec<BTreeMap<String, String>> = read_csv(&steps_path)?;
        let ch = channel(
            &mut w,
            "std_msgs/msg/String",
            definition("string data", &[]),
            "/steps",
        )?;
        for row in &rows {
            let t = row
                .get("t_end_ns")
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(0);
            let mut c = Cdr::new();
            c.string(&serde_json::Value::Object(json_row(row)).to_string());
            put(&mut w, ch, "/steps", t, c.finish())?;
        }
    }
    // The live tactile state of grasp trials: each row of `tactile.csv` as JSON at its frame.
    let tactile_path = run_dir.join("tactile.csv");
    if tactile_path.is_file() {
        let rows: Vec<BTreeMap<String, String>> = read_csv(&tactile_path)?;
        let ch = channel(
            &mut w,
            "std_msgs/msg/String",
            definition("string data", &[]),
            "/tactile",
        )?;
        for row in &rows {
            let t = row
                .get("t_ns")
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(0);
            let mut c = Cdr::new();
            c.string(&serde_json::Value::Object(json_row(row)).to_string());
            put(&mut w, ch, "/tactile", t, c.finish())?;
        }
    }
    // The run's own files, and what it was.
    for (name, media) in [
        ("protocol.yaml", "application/yaml"),
        ("rig.yaml", "application/yaml"),
        ("run.yaml", "application/yaml"),
    ] {
        if let Ok(bytes) = std::fs::read(run_dir.join(name)) {
            w.attach(&mcap::Attachment {
                log_time: 0,
                create_time: 0,
                name: name.to_string(),
                media_type: media.to_string(),
                data: Cow::Owned(bytes),
            })
            .map_err(m)?;
        }
    }
    if let Ok(manifest) = crate::record::read_manifest(run_dir) {
        let metadata: BTreeMap<String, String> = [
            ("protocol", manifest.protocol.clone()),
            ("status", manifest.status.name().to_string()),
            ("seed", manifest.seed.to_string()),
            ("rig", manifest.rig.clone()),
            ("started_utc", manifest.started_utc.clone()),
            ("gelrig_version", manifest.gelrig_version.clone()),
            ("clock", manifest.clock.clone()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        w.write_metadata(&mcap::records::Metadata {
            name: "gelrig_run".into(),
            metadata,
        })
        .map_err(m)?;
    }
    w.finish().map_err(m)?;
    Ok(Exported {
        path: out.to_path_buf(),
        messages: counts,
    })
}
