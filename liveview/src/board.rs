//! What the page shows, kept as the run goes: the runner writes to a [`Board`], the server
//! reads snapshots of it. Every part is bounded (a ten-hour run holds as much as a
//! ten-minute one): the force history is decimated ([`History`]), the step list, the
//! force–position curve, the settle trace and the notes keep their newest entries, and
//! only the latest frame (with the run's first, the reference of its marker field) is kept.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use serde::Serialize;

use crate::history::{History, Series};

/// Buckets of the force history.
const HISTORY_BUCKETS: usize = 1500;
/// Width of a history bucket at the start, before any merge: 5 ms.
const FIRST_BUCKET_NS: u64 = 5_000_000;
/// Steps, curve points and settle points kept (the newest).
const KEEP_STEPS: usize = 2000;
const KEEP_SETTLE: usize = 600;
const KEEP_NOTES: usize = 40;

/// What is known before the run starts.
#[derive(Debug, Clone, Serialize)]
pub struct RunMeta {
    /// Run directory (as the runner names it).
    pub dir: String,
    /// Protocol name.
    pub protocol: String,
    /// Rig name.
    pub rig: String,
    /// Steps the plan has.
    pub steps_planned: u32,
    /// Planned duration, s of run time (upper estimate).
    pub eta_s: f64,
    /// How much faster than the wall the run clock goes (`None`: virtual time).
    pub time_scale: Option<f64>,
    /// Safety limits, for the margins: |Fz| N, |Fxy| N, |Tz| N·mm.
    pub max_fz_n: f64,
    /// Shear force limit, N.
    pub max_fxy_n: f64,
    /// Torque limit, N·mm.
    pub max_tz_nmm: f64,
    /// The page follows a run as it goes (false: a finished run read from its directory).
    pub live: bool,
}

/// A step's span on the time axis (for the shading).
#[derive(Debug, Clone, Serialize)]
pub struct StepSpan {
    /// Step number (1-based).
    pub step: u32,
    /// Trial of a repeated block (0: none).
    pub trial: u32,
    /// Label (`load`, `unload`, `grip`, …).
    pub label: String,
    /// Start, s.
    pub t0_s: f64,
    /// End, s.
    pub t1_s: f64,
}

/// A settled step's quasistatic force at its position (force against depth).
#[derive(Debug, Clone, Serialize)]
pub struct CurvePoint {
    /// Step number.
    pub step: u32,
    /// Label (`load`, `unload`, …).
    pub label: String,
    /// The axis the step moved.
    pub axis: String,
    /// Its position after the step.
    pub position: f64,
    /// Unit of the position (`mm`, `deg`).
    pub unit: String,
    /// The step's window-mean wrench: Fx, Fy, Fz (N), Tz (N·mm).
    pub wrench: [f64; 4],
}

/// The settle rule's statistic against its threshold, in the step settling now.
#[derive(Debug, Clone, Serialize)]
pub struct Settle {
    /// The step.
    pub step: u32,
    /// Statistic (a drift bound, per s) and threshold, in `unit`.
    pub bound: f64,
    /// Threshold.
    pub below: f64,
    /// Unit of both (`N/s`, `N·mm/s`).
    pub unit: String,
    /// Trace of the statistic: (s since the settle began, value).
    pub trace: VecDeque<(f64, f64)>,
    /// Settle start, ns.
    #[serde(skip)]
    start_ns: u64,
}

/// The latest frame (or the reference), pixels shared with the server.
#[derive(Debug, Clone)]
pub struct FrameImage {
    /// Frame number in the run.
    pub index: u64,
    /// Exposure time, ns.
    pub t_ns: u64,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// RGB8 pixels.
    pub rgb: Arc<Vec<u8>>,
}

/// Marker arrows and contact outline of a frame, in the frame's pixels.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Overlay {
    /// The frame it belongs to.
    pub index: u64,
    /// Per measured marker: reference x, y and displacement dx, dy (px).
    pub arrows: Vec<[f64; 4]>,
    /// Contact outline (closed), px; empty when no contact is seen.
    pub outline: Vec<[f64; 2]>,
    /// Why there are no arrows, when there are none.
    pub note: Option<String>,
}

/// The grasp's live tactile state.
#[derive(Debug, Clone, Serialize)]
pub struct Tactile {
    /// Slip state (`stick`, `partial`, `slip`, …).
    pub state: String,
    /// The grip is closed.
    pub gripping: bool,
    /// Fraction of the contact still stuck.
    pub stuck_fraction: f64,
    /// Frame time, s.
    pub t_s: f64,
    /// The GelSight's own Fz, N, when the protocol reads it live.
    pub gelsight_fz_n: Option<f64>,
}

#[derive(Debug)]
struct State {
    meta: RunMeta,
    t_ns: u64,
    force: History,
    latest: Option<[f64; 4]>,
    lost_records: Option<u64>,
    step: u32,
    trial: u32,
    what: String,
    phase: String,
    steps_done: u32,
    step_start_ns: Option<u64>,
    spans: VecDeque<StepSpan>,
    curve: VecDeque<CurvePoint>,
    settle: Option<Settle>,
    reference: Option<FrameImage>,
    frame: Option<FrameImage>,
    frames: u64,
    last_frame_seq: Option<u64>,
    frames_dropped: u64,
    overlay: Option<Overlay>,
    tactile: Option<Tactile>,
    notes: VecDeque<String>,
    status: String,
    message: Option<String>,
    updates: u64,
}

/// The live state of one run.
#[derive(Debug)]
pub struct Board {
    state: Mutex<State>,
}

/// One snapshot, as `state.json`.
#[derive(Debug, Serialize)]
pub struct Snapshot {
    /// What was known before the run.
    pub meta: RunMeta,
    /// Updates so far (a page sees whether anything changed).
    pub updates: u64,
    /// Run status (`running`, `completed`, `aborted`, `failed`) and its message.
    pub status: String,
    /// Why the run ended, if it did not complete.
    pub message: Option<String>,
    /// Run time, s.
    pub t_s: f64,
    /// Planned run time left, s (run time; the page divides by the time scale).
    pub left_s: f64,
    /// The step under way (0: between steps), its trial, what it does and its phase.
    pub step: u32,
    /// Trial.
    pub trial: u32,
    /// What the step does.
    pub what: String,
    /// Phase (`moving`, `settling`, `capturing`, …).
    pub phase: String,
    /// Steps completed.
    pub steps_done: u32,
    /// Force history (Fx, Fy, Fz, Tz).
    pub force: Series,
    /// Latest wrench.
    pub latest: Option<[f64; 4]>,
    /// Margin to each safety limit, fraction of the limit left (Fz, Fxy, Tz).
    pub margins: Option<[f64; 3]>,
    /// Force records lost (`None`: not known, e.g. a finished run read from disk).
    pub lost_records: Option<u64>,
    /// Frames recorded, and frames missing from the camera's sequence.
    pub frames: u64,
    /// Frames the camera's counter skipped.
    pub frames_dropped: u64,
    /// The latest frame's number, if any.
    pub frame_index: Option<u64>,
    /// Steps' spans.
    pub spans: Vec<StepSpan>,
    /// Force against position, one point per settled step.
    pub curve: Vec<CurvePoint>,
    /// The settle rule's statistic, while a step settles on one.
    pub settle: Option<Settle>,
    /// The grasp's tactile state.
    pub tactile: Option<Tactile>,
    /// Notable lines (contact found, warnings, the end).
    pub notes: Vec<String>,
}

fn push_capped<T>(q: &mut VecDeque<T>, v: T, cap: usize) {
    if q.len() == cap {
        q.pop_front();
    }
    q.push_back(v);
}

/// Frames missing before one with camera counter `seq` in a stream that takes every
/// `stride`-th frame, after the stream's previous frame `last`: a jump of more than 20
/// strides is the stream pausing (a record block ended), not frames dropped.
fn gap(last: &mut Option<u64>, seq: u64, stride: u64) -> u64 {
    let stride = stride.max(1);
    let missed = match *last {
        Some(p) if seq > p + stride && seq - p <= 20 * stride => {
            (seq - p - stride).div_ceil(stride)
        }
        _ => 0,
    };
    if last.is_none_or(|p| seq > p) {
        *last = Some(seq);
    }
    missed
}

impl Board {
    /// A board for a run about to start.
    pub fn new(meta: RunMeta) -> Arc<Self> {
        Arc::new(Self {
            state: Mutex::new(State {
                meta,
                t_ns: 0,
                force: History::new(HISTORY_BUCKETS, FIRST_BUCKET_NS),
                latest: None,
                lost_records: None,
                step: 0,
                trial: 0,
                what: String::new(),
                phase: "starting".into(),
                steps_done: 0,
                step_start_ns: None,
                spans: VecDeque::new(),
                curve: VecDeque::new(),
                settle: None,
                reference: None,
                frame: None,
                frames: 0,
                last_frame_seq: None,
                frames_dropped: 0,
                overlay: None,
                tactile: None,
                notes: VecDeque::new(),
                status: "running".into(),
                message: None,
                updates: 0,
            }),
        })
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        let mut s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        s.updates += 1;
        s
    }

    /// A tared force reading: Fx, Fy, Fz (N), Tz (N·mm).
    pub fn force(&self, t_ns: u64, wrench: [f64; 4]) {
        let mut s = self.lock();
        s.t_ns = s.t_ns.max(t_ns);
        s.force.push(t_ns, wrench);
        s.latest = Some(wrench);
    }

    /// Force records lost so far: missing from the sensor's own sequence (a Net F/T's
    /// `rdt_sequence`), or read but not taken by the run in time.
    pub fn lost_records(&self, n: u64) {
        self.lock().lost_records = Some(n);
    }

    /// The step (0: between steps), its trial, what it does and its phase, at run time `t_ns`.
    pub fn phase(&self, step: u32, trial: u32, what: &str, phase: &str, t_ns: u64) {
        let mut s = self.lock();
        s.t_ns = s.t_ns.max(t_ns);
        if step != s.step && step > 0 {
            s.step_start_ns = Some(t_ns);
            s.settle = None;
        }
        s.step = step;
        s.trial = trial;
        if s.what != what {
            s.what = what.to_string();
        }
        if s.phase != phase {
            s.phase = phase.to_string();
        }
    }

    /// The settle rule's statistic (`bound`) against `below`, in `unit`, at `t_ns` of a
    /// settle that began at `start_ns`.
    pub fn settle(&self, start_ns: u64, t_ns: u64, bound: f64, below: f64, unit: &str) {
        let mut s = self.lock();
        s.t_ns = s.t_ns.max(t_ns);
        let step = s.step;
        let fresh = !s
            .settle
            .as_ref()
            .is_some_and(|x| x.step == step && x.start_ns == start_ns);
        if fresh {
            s.settle = Some(Settle {
                step,
                bound,
                below,
                unit: unit.to_string(),
                trace: VecDeque::new(),
                start_ns,
            });
        }
        if let Some(x) = s.settle.as_mut() {
            x.bound = bound;
            x.below = below;
            let at = t_ns.saturating_sub(start_ns) as f64 * 1e-9;
            push_capped(&mut x.trace, (at, bound), KEEP_SETTLE);
        }
    }

    /// A step is done: its span, and its point on the force–position curve.
    pub fn step_done(&self, point: CurvePoint, trial: u32, t_start_ns: u64, t_end_ns: u64) {
        let mut s = self.lock();
        s.steps_done = s.steps_done.max(point.step);
        s.t_ns = s.t_ns.max(t_end_ns);
        let span = StepSpan {
            step: point.step,
            trial,
            label: point.label.clone(),
            t0_s: t_start_ns as f64 * 1e-9,
            t1_s: t_end_ns as f64 * 1e-9,
        };
        push_capped(&mut s.spans, span, KEEP_STEPS);
        if point.position.is_finite() {
            push_capped(&mut s.curve, point, KEEP_STEPS);
        }
    }

    /// A frame was recorded as number `index`; `seq` is the camera's counter and
    /// `stream_stride` the counter's step between frames of a continuous frame stream
    /// (1 at the camera's rate; `None` outside a stream). A larger step drops frames.
    pub fn frame(
        &self,
        index: u64,
        t_ns: u64,
        seq: (u64, Option<u64>),
        size: (u32, u32),
        rgb: &[u8],
    ) {
        let image = FrameImage {
            index,
            t_ns,
            width: size.0,
            height: size.1,
            rgb: Arc::new(rgb.to_vec()),
        };
        let mut s = self.lock();
        Self::count_frame(&mut s, t_ns, seq);
        if s.reference.is_none() {
            s.reference = Some(image.clone());
        }
        s.frame = Some(image);
    }

    /// A frame was recorded but its pixels are not kept (a finished run's middle frames).
    pub fn frame_seen(&self, t_ns: u64, seq: (u64, Option<u64>)) {
        Self::count_frame(&mut self.lock(), t_ns, seq);
    }

    fn count_frame(s: &mut State, t_ns: u64, (seq, stride): (u64, Option<u64>)) {
        s.frames += 1;
        s.t_ns = s.t_ns.max(t_ns);
        match stride {
            Some(k) => {
                let dropped = gap(&mut s.last_frame_seq, seq, k);
                s.frames_dropped += dropped;
            }
            None => s.last_frame_seq = None,
        }
    }

    /// The run directory, once the recorder has made it.
    pub fn set_dir(&self, dir: &str) {
        self.lock().meta.dir = dir.to_string();
    }

    /// The marker field of frame `overlay.index`, measured by the run itself (the grasp's
    /// live tracking); the server tracks other frames itself when the page asks.
    pub fn overlay(&self, overlay: Overlay) {
        self.lock().overlay = Some(overlay);
    }

    /// The grasp's tactile state.
    pub fn tactile(&self, t: Tactile) {
        self.lock().tactile = Some(t);
    }

    /// A notable line.
    pub fn note(&self, line: &str) {
        push_capped(&mut self.lock().notes, line.to_string(), KEEP_NOTES);
    }

    /// The run ended with `status` (`completed`, `aborted`, `failed`).
    pub fn finished(&self, status: &str, message: Option<&str>) {
        let mut s = self.lock();
        s.status = status.to_string();
        s.message = message.map(str::to_string);
        s.phase = "ended".into();
        s.settle = None;
    }

    /// The latest frame and the reference (the run's first frame).
    pub fn frames(&self) -> (Option<FrameImage>, Option<FrameImage>) {
        let s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        (s.frame.clone(), s.reference.clone())
    }

    /// The run's own overlay of frame `index`, if it tracked that frame.
    pub fn overlay_of(&self, index: u64) -> Option<Overlay> {
        let s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        s.overlay.as_ref().filter(|o| o.index == index).cloned()
    }

    /// Everything the page shows, now.
    pub fn snapshot(&self) -> Snapshot {
        let s = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        let t_s = s.t_ns as f64 * 1e-9;
        let margins = s.latest.map(|w| {
            let m = |v: f64, limit: f64| ((1.0 - v.abs() / limit) * 1e4).round() / 1e4;
            [
                m(w[2], s.meta.max_fz_n),
                m(w[0].hypot(w[1]), s.meta.max_fxy_n),
                m(w[3], s.meta.max_tz_nmm),
            ]
        });
        Snapshot {
            meta: s.meta.clone(),
            updates: s.updates,
            status: s.status.clone(),
            message: s.message.clone(),
            t_s,
            left_s: if s.status == "running" {
                (s.meta.eta_s - t_s).max(0.0)
            } else {
                0.0
            },
            step: s.step,
            trial: s.trial,
            what: s.what.clone(),
            phase: s.phase.clone(),
            steps_done: s.steps_done,
            force: s.force.series(),
            latest: s.latest,
            margins,
            lost_records: s.lost_records,
            frames: s.frames,
            frames_dropped: s.frames_dropped,
            frame_index: s.frame.as_ref().map(|f| f.index),
            spans: s.spans.iter().cloned().collect(),
            curve: s.curve.iter().cloned().collect(),
            settle: s.settle.clone(),
            tactile: s.tactile.clone(),
            notes: s.notes.iter().cloned().collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta() -> RunMeta {
        RunMeta {
            dir: "r".into(),
            protocol: "p".into(),
            rig: "sim".into(),
            steps_planned: 3,
            eta_s: 100.0,
            time_scale: None,
            max_fz_n: 10.0,
            max_fxy_n: 5.0,
            max_tz_nmm: 20.0,
            live: true,
        }
    }

    #[test]
    fn frames_missing_from_a_stream_are_counted_and_pauses_are_not() {
        let b = Board::new(meta());
        // Every frame (stride 1): 3 → 5 drops one. Then a capture outside a stream, then a
        // stream taking every 4th frame: 104 → 112 drops one, 112 → 400 is a pause.
        let frames = [
            (0, Some(1)),
            (1, Some(1)),
            (2, Some(1)),
            (3, Some(1)),
            (5, Some(1)),
            (40, None),
            (100, Some(4)),
            (104, Some(4)),
            (112, Some(4)),
            (400, Some(4)),
        ];
        for (i, (seq, stride)) in frames.into_iter().enumerate() {
            b.frame(i as u64, seq * 1000, (seq, stride), (2, 1), &[0; 6]);
        }
        let s = b.snapshot();
        assert_eq!(s.frames, 10);
        assert_eq!(s.frames_dropped, 1 + 1);
        assert_eq!(s.frame_index, Some(9));
        assert_eq!(s.lost_records, None);
        b.lost_records(3);
        assert_eq!(b.snapshot().lost_records, Some(3));
        // The reference stays the first frame.
        assert_eq!(b.frames().1.map(|f| f.index), Some(0));
    }

    #[test]
    fn margins_time_left_and_steps() {
        let b = Board::new(meta());
        b.phase(1, 0, "load → 0.1 mm", "moving", 10_000_000_000);
        b.force(10_000_000_000, [3.0, 4.0, -2.5, 5.0]);
        b.settle(10_000_000_000, 12_000_000_000, 0.5, 0.01, "N/s");
        b.settle(10_000_000_000, 13_000_000_000, 0.2, 0.01, "N/s");
        let s = b.snapshot();
        assert_eq!(s.margins, Some([0.75, 0.0, 0.75]));
        assert!((s.left_s - 87.0).abs() < 1e-9);
        let settle = s.settle.expect("settling");
        assert_eq!(settle.trace.len(), 2);
        assert_eq!(settle.bound, 0.2);
        let point = CurvePoint {
            step: 1,
            label: "load".into(),
            axis: "z".into(),
            position: 0.1,
            unit: "mm".into(),
            wrench: [0.0, 0.0, 1.2, 0.0],
        };
        b.step_done(point, 0, 10_000_000_000, 14_000_000_000);
        b.phase(2, 0, "load → 0.2 mm", "moving", 14_000_000_000);
        let s = b.snapshot();
        assert_eq!(s.steps_done, 1);
        assert_eq!(s.curve.len(), 1);
        assert!(s.settle.is_none(), "a new step clears the settle trace");
        b.finished("completed", None);
        assert_eq!(b.snapshot().left_s, 0.0);
    }
}
