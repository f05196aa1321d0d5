//! A run's messages as ROS 2 types in MCAP, one per call: what `gelrig export --format mcap`
//! writes from a finished run and what `gelrig run --record mcap` writes as the run goes.
//! Channels are added on a topic's first message; schemas carry their dependencies as ROS 2
//! bags do (`ros2msg`, sections separated by a line of `=`).

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::{Seek, Write};

mod cdr;

use cdr::Cdr;

const SEP: &str =
    "================================================================================";
const HEADER: &str = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id";
const TIME: &str = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec";
const DURATION: &str = "MSG: builtin_interfaces/Duration\nint32 sec\nuint32 nanosec";
const POINT: &str = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z";
const COLOR: &str = "MSG: std_msgs/ColorRGBA\nfloat32 r\nfloat32 g\nfloat32 b\nfloat32 a";

/// `.msg` definition of a type with its dependencies.
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

/// The topics and their types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Topic {
    Force,
    Image,
    Markers,
    Stages,
    Steps,
    Tactile,
}

impl Topic {
    pub(crate) fn name(self) -> &'static str {
        match self {
            Topic::Force => "/force",
            Topic::Image => "/camera/image/compressed",
            Topic::Markers => "/camera/markers",
            Topic::Stages => "/stages",
            Topic::Steps => "/steps",
            Topic::Tactile => "/tactile",
        }
    }

    fn schema(self) -> (&'static str, String) {
        match self {
            Topic::Force => (
                "geometry_msgs/msg/WrenchStamped",
                definition(
                    "std_msgs/Header header\nWrench wrench",
                    &[
                        HEADER,
                        TIME,
                        "MSG: geometry_msgs/Wrench\nVector3  force\nVector3  torque",
                        "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z",
                    ],
                ),
            ),
            Topic::Image => (
                "sensor_msgs/msg/CompressedImage",
                definition(
                    "std_msgs/Header header\nstring format\nuint8[] data",
                    &[HEADER, TIME],
                ),
            ),
            Topic::Markers => (
                "visualization_msgs/msg/ImageMarker",
                definition(
                    "uint8 CIRCLE=0\nuint8 LINE_STRIP=1\nuint8 LINE_LIST=2\nuint8 POLYGON=3\n\
                     uint8 POINTS=4\nuint8 ADD=0\nuint8 REMOVE=1\n\
                     std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\n\
                     geometry_msgs/Point position\nfloat32 scale\n\
                     std_msgs/ColorRGBA outline_color\nuint8 filled\n\
                     std_msgs/ColorRGBA fill_color\nbuiltin_interfaces/Duration lifetime\n\
                     geometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] outline_colors",
                    &[HEADER, TIME, POINT, COLOR, DURATION],
                ),
            ),
            Topic::Stages => (
                "sensor_msgs/msg/JointState",
                definition(
                    "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort",
                    &[HEADER, TIME],
                ),
            ),
            Topic::Steps | Topic::Tactile => {
                ("std_msgs/msg/String", definition("string data", &[]))
            }
        }
    }
}

/// An MCAP file being written with ROS 2 messages.
pub(crate) struct Ros2Mcap<W: Write + Seek> {
    w: mcap::Writer<W>,
    channels: BTreeMap<Topic, u16>,
    counts: BTreeMap<String, usize>,
}

impl<W: Write + Seek> Ros2Mcap<W> {
    pub(crate) fn create(out: W) -> Result<Self, mcap::McapError> {
        let w = mcap::WriteOptions::new()
            .profile("ros2")
            .library(format!("gelrig {}", env!("CARGO_PKG_VERSION")))
            .compression(None)
            .create(out)?;
        Ok(Self {
            w,
            channels: BTreeMap::new(),
            counts: BTreeMap::new(),
        })
    }

    fn put(&mut self, topic: Topic, t_ns: u64, data: &[u8]) -> Result<(), mcap::McapError> {
        let ch = match self.channels.get(&topic) {
            Some(c) => *c,
            None => {
                let (name, def) = topic.schema();
                let schema = self.w.add_schema(name, "ros2msg", def.as_bytes())?;
                let c = self
                    .w
                    .add_channel(schema, topic.name(), "cdr", &BTreeMap::new())?;
                self.channels.insert(topic, c);
                c
            }
        };
        let n = self.counts.entry(topic.name().to_string()).or_default();
        self.w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: *n as u32,
                log_time: t_ns,
                publish_time: t_ns,
            },
            data,
        )?;
        *n += 1;
        Ok(())
    }

    /// `/force`: Fx, Fy, Fz in N and Tx, Ty, Tz given in N·mm, written in N·m (SI, as ROS
    /// expects).
    pub(crate) fn wrench(&mut self, t_ns: u64, w: [f64; 6]) -> Result<(), mcap::McapError> {
        let mut c = Cdr::new();
        c.header(t_ns, "force_sensor")
            .f64(w[0])
            .f64(w[1])
            .f64(w[2])
            .f64(w[3] / 1000.0)
            .f64(w[4] / 1000.0)
            .f64(w[5] / 1000.0);
        self.put(Topic::Force, t_ns, &c.finish())
    }

    /// `/camera/image/compressed`: a PNG as recorded.
    pub(crate) fn png(&mut self, t_ns: u64, bytes: &[u8]) -> Result<(), mcap::McapError> {
        let mut c = Cdr::new();
        c.header(t_ns, "camera").string("png").bytes(bytes);
        self.put(Topic::Image, t_ns, &c.finish())
    }

    /// `/camera/markers`: each marker's displacement as a line from its reference position
    /// to where it is now, in the image's pixels (an `ImageMarker` LINE_LIST, drawn over the
    /// image by viewers that overlay image markers).
    pub(crate) fn markers(
        &mut self,
        t_ns: u64,
        frame: u64,
        lines_px: &[[f64; 4]],
    ) -> Result<(), mcap::McapError> {
        let mut c = Cdr::new();
        c.header(t_ns, "camera")
            .string("marker_displacement")
            .i32(frame.min(i32::MAX as u64) as i32)
            .i32(2) // LINE_LIST
            .i32(0) // ADD
            .f64(0.0)
            .f64(0.0)
            .f64(0.0)
            .f32(1.0)
            .f32x4([1.0, 0.85, 0.0, 1.0])
            .u8(0)
            .f32x4([0.0; 4])
            .i32(0)
            .u32(0)
            .u32(2 * lines_px.len() as u32);
        for [x, y, dx, dy] in lines_px {
            c.f64(*x).f64(*y).f64(0.0).f64(x + dx).f64(y + dy).f64(0.0);
        }
        c.u32(0);
        self.put(Topic::Markers, t_ns, &c.finish())
    }

    /// `/stages`: one axis's position, already in SI (m or rad).
    pub(crate) fn joint(&mut self, t_ns: u64, axis: &str, si: f64) -> Result<(), mcap::McapError> {
        let mut c = Cdr::new();
        c.header(t_ns, "stages")
            .strings(&[axis.to_string()])
            .f64s(&[si])
            .f64s(&[])
            .f64s(&[]);
        self.put(Topic::Stages, t_ns, &c.finish())
    }

    /// `/steps` or `/tactile`: a row as JSON text.
    pub(crate) fn json(
        &mut self,
        topic: Topic,
        t_ns: u64,
        text: &str,
    ) -> Result<(), mcap::McapError> {
        let mut c = Cdr::new();
        c.string(text);
        self.put(topic, t_ns, &c.finish())
    }

    /// A file of the run, attached.
    pub(crate) fn attach(&mut self, name: &str, bytes: Vec<u8>) -> Result<(), mcap::McapError> {
        self.w.attach(&mcap::Attachment {
            log_time: 0,
            create_time: 0,
            name: name.to_string(),
            media_type: "application/yaml".into(),
            data: Cow::Owned(bytes),
        })
    }

    /// The run's headline (protocol, status, seed…) as the `gelrig_run` metadata record.
    pub(crate) fn run_metadata(
        &mut self,
        metadata: BTreeMap<String, String>,
    ) -> Result<(), mcap::McapError> {
        self.w.write_metadata(&mcap::records::Metadata {
            name: "gelrig_run".into(),
            metadata,
        })
    }

    /// Writes the summary and index; the counts of messages per topic.
    pub(crate) fn finish(mut self) -> Result<BTreeMap<String, usize>, mcap::McapError> {
        self.w.finish()?;
        Ok(self.counts)
    }
}

/// The rotary axes of a rig file (their positions are degrees; the others mm): those whose
/// travel a rig file writes in an angle. Only the travel is read, so the run directory's
/// reader needs nothing of the device layer.
pub(crate) fn rotary_axes(rig_yaml: &str) -> Vec<String> {
    #[derive(serde::Deserialize)]
    struct Axis {
        travel: [records::units::AxisQuantity; 2],
    }
    #[derive(serde::Deserialize)]
    struct Rig {
        #[serde(default)]
        axes: BTreeMap<String, Axis>,
    }
    /// Only the axes' travels, whatever else the file holds.
    fn axes_only(text: &str) -> Option<Rig> {
        let value: serde_yaml::Value = serde_yaml::from_str(text).ok()?;
        let axes = value.get("axes")?.as_mapping()?;
        let mut kept = serde_yaml::Mapping::new();
        for (role, axis) in axes {
            if let Some(travel) = axis.get("travel") {
                let mut m = serde_yaml::Mapping::new();
                m.insert("travel".into(), travel.clone());
                kept.insert(role.clone(), serde_yaml::Value::Mapping(m));
            }
        }
        let mut top = serde_yaml::Mapping::new();
        top.insert("axes".into(), serde_yaml::Value::Mapping(kept));
        serde_yaml::from_value(serde_yaml::Value::Mapping(top)).ok()
    }
    axes_only(rig_yaml)
        .map(|rig| {
            rig.axes
                .into_iter()
                .filter(|(_, a)| a.travel[0].natural_unit() == records::units::AxisUnit::Deg)
                .map(|(r, _)| r)
                .collect()
        })
        .unwrap_or_default()
}

/// A position in the axis's unit (mm or deg) in SI (m or rad).
pub(crate) fn si(position: f64, rotary: bool) -> f64 {
    if rotary {
        position.to_radians()
    } else {
        position / 1000.0
    }
}
