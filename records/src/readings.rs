//! What devices hand over and runs record: force samples and their wrenches, frames, the
//! simulated bench's truth, and how a device's times were put on the run's timebase. Plain
//! data, shared by the device layer (`rig`), the simulated bench and the run directory
//! (`rundir`), so that a run's files depend on nothing that drives hardware.

use serde::Serialize;

/// Force in N and torque in N·mm, as the sensor reports them: the load the indenter applies
/// to the elastomer, with z into the gel and x along the shear axis.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Wrench {
    /// Force along x (shear axis), N.
    pub fx_n: f64,
    /// Force along y, N.
    pub fy_n: f64,
    /// Force along z (into the gel), N.
    pub fz_n: f64,
    /// Torque about x, N·mm.
    pub tx_nmm: f64,
    /// Torque about y, N·mm.
    pub ty_nmm: f64,
    /// Torque about z (normal axis), N·mm.
    pub tz_nmm: f64,
}

impl Wrench {
    /// Component-wise difference (used for tare).
    pub fn minus(&self, o: &Wrench) -> Wrench {
        Wrench {
            fx_n: self.fx_n - o.fx_n,
            fy_n: self.fy_n - o.fy_n,
            fz_n: self.fz_n - o.fz_n,
            tx_nmm: self.tx_nmm - o.tx_nmm,
            ty_nmm: self.ty_nmm - o.ty_nmm,
            tz_nmm: self.tz_nmm - o.tz_nmm,
        }
    }

    /// Component-wise mean of `ws` (zero for an empty slice).
    pub fn mean(ws: impl IntoIterator<Item = Wrench>) -> Wrench {
        let mut sum = [0.0; 6];
        let mut n = 0usize;
        for w in ws {
            for (s, v) in sum.iter_mut().zip(w.as_array()) {
                *s += v;
            }
            n += 1;
        }
        let k = if n == 0 { 0.0 } else { 1.0 / n as f64 };
        Wrench::from_array(sum.map(|s| s * k))
    }

    /// `[fx, fy, fz, tx, ty, tz]`.
    pub fn as_array(&self) -> [f64; 6] {
        [
            self.fx_n,
            self.fy_n,
            self.fz_n,
            self.tx_nmm,
            self.ty_nmm,
            self.tz_nmm,
        ]
    }

    /// Inverse of [`Wrench::as_array`].
    pub fn from_array(a: [f64; 6]) -> Wrench {
        Wrench {
            fx_n: a[0],
            fy_n: a[1],
            fz_n: a[2],
            tx_nmm: a[3],
            ty_nmm: a[4],
            tz_nmm: a[5],
        }
    }
}

/// Status bit: some channel is beyond the sensor's calibrated range (the reading is clipped).
pub const STATUS_SATURATED: u32 = 1 << 30;

/// One force/torque sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ForceSample {
    /// Host time of the sample on the run's timebase.
    pub t_ns: u64,
    /// The sensor's own sample counter (Net F/T `ft_sequence`; the simulator's count).
    pub ft_seq: u64,
    /// The reading, before any tare.
    pub wrench: Wrench,
    /// Device status bits; see [`STATUS_SATURATED`].
    pub status: u32,
}

/// What a simulated bench knows that no sensor can: the contact's true state, recorded
/// beside the data of a dry run so analysis can be checked against it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimTruth {
    /// Indentation depth, mm.
    pub depth_mm: f64,
    /// The wrench without sensor offset, noise or quantisation.
    pub wrench: Wrench,
    /// The long-term (fully relaxed) wrench of the present state.
    pub equilibrium: Wrench,
    /// Effective contact radius √(A/π), mm.
    pub contact_radius_mm: f64,
    /// Fraction of the contact that sticks under shear (None without shear).
    pub shear_stick_fraction: Option<f64>,
    /// Fraction of the contact that sticks under twist (None without twist).
    pub twist_stick_fraction: Option<f64>,
    /// Sliding in full slip under shear.
    pub shear_sliding: bool,
    /// Sliding in full slip under twist.
    pub twist_sliding: bool,
    /// Times the contact went into full slip under shear since it was made.
    pub shear_slips: u32,
    /// Times the contact went into full slip under twist since it was made.
    pub twist_slips: u32,
    /// Times a grasped object slipped out of the grasp.
    pub object_slips: u32,
    /// The grasped can's motion and the gel's stick state (lifting trials only).
    pub grasp: Option<GraspTruth>,
}

/// Ground truth of a simulated grasp (thesis §6.3): what tactile slip detection is scored
/// against.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct GraspTruth {
    /// The can's height above where it stood on the table, mm.
    pub height_mm: f64,
    /// The can's velocity relative to the pads, mm/s (negative: sliding down).
    pub slip_mm_s: f64,
    /// How far the can has slid through the grasp since it was taken, mm.
    pub slid_mm: f64,
    /// The can's rotation in the grasp, degrees.
    pub angle_deg: f64,
    /// Fraction of the gel's contact that sticks under the load along the lift (1 at rest,
    /// 0 in gross slip).
    pub gel_stick_fraction: f64,
    /// Fraction that sticks under the torque about the normal alone. Under both loads the
    /// stuck area is at most the smaller of the two.
    pub gel_twist_stick_fraction: f64,
    /// The gel side's friction margin along the lift, 1 − |Q| / Q_max (Q_max: its full-slip
    /// force at the present squeeze); 1 when it carries nothing.
    pub gel_margin: f64,
    /// The gel side's torsional margin, 1 − |M| / M_max.
    pub gel_twist_margin: f64,
    /// Gross slip on the gel side now.
    pub sliding: bool,
    /// The can turns in the grasp now (the gel's twist in full slip).
    pub rotating: bool,
    /// The can stands on the table.
    pub on_table: bool,
    /// Gross slips through the grasp so far.
    pub slips: u32,
    /// Falls from the air back onto the table so far.
    pub drops: u32,
}

/// How a device's sample times are put on the run's timebase.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct DeviceTiming {
    /// The method, in words ("sample counter against arrival times (lower envelope)").
    pub method: String,
    /// The constant latency subtracted, s (calibrated per setup: no model of arrival times
    /// can tell it from a clock offset).
    pub latency_s: f64,
    /// The device clock's rate against the host's, ppm (positive: slow), once fitted.
    pub drift_ppm: Option<f64>,
    /// Samples stamped on arrival, before the model had seen enough.
    pub stamped_on_arrival: u64,
}

/// One RGB frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Host time of the exposure midpoint on the run's timebase.
    pub t_ns: u64,
    /// The camera's frame counter; gaps mean dropped frames.
    pub seq: u64,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major RGB8 pixels, `width * height * 3` bytes.
    pub rgb: Vec<u8>,
    /// Exact marker centres in pixels, when the camera is simulated (ground truth for
    /// tracking tests); `None` from a real camera.
    pub truth_px: Option<Vec<[f64; 2]>>,
    /// The true exposure midpoint, ns, when the camera is simulated (what `t_ns` is
    /// measured against); `None` from a real camera.
    pub truth_t_ns: Option<u64>,
    /// The simulator's tractions and contact under this frame, when a simulated camera was
    /// asked for them (a dataset run's `record: {traction_maps: true}`); `None` otherwise.
    pub truth_surface: Option<Box<SurfaceTruth>>,
}

/// What the simulator knew of the gel's surface under one frame: the tractions the indenter
/// put on it, as maps on a grid `px_per_cell` times coarser than the frame (cell (i, j)
/// covers frame pixels `[i·k, (i+1)·k) × [j·k, (j+1)·k)`), and the contact's state. Labels no
/// real bench can measure, for learning force and contact from images.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SurfaceTruth {
    /// Map width, cells.
    pub width: u32,
    /// Map height, cells.
    pub height: u32,
    /// Frame pixels per map cell, along each side.
    pub px_per_cell: u32,
    /// Map cell side on the gel, mm.
    pub cell_mm: f64,
    /// Normal pressure, compressive positive, kPa (the cell's mean), row-major.
    pub pressure_kpa: Vec<f32>,
    /// Tangential traction on the gel along the frame's x (right), kPa.
    pub shear_x_kpa: Vec<f32>,
    /// Tangential traction on the gel along the frame's y (down), kPa.
    pub shear_y_kpa: Vec<f32>,
    /// 1 where the cell's centre is in contact (pressure there above 1 % of the frame's peak).
    pub contact: Vec<u8>,
    /// Indentation depth, mm.
    pub depth_mm: f64,
    /// Tangential force the contact carries along x (its elastic part), N.
    pub shear_n: f64,
    /// Twisting moment the contact carries (its elastic part), N·mm.
    pub torque_nmm: f64,
    /// Where the contact's centre is in the view, mm from the view's centre (x right, y down).
    pub centre_mm: (f64, f64),
    /// How far the contact has turned by slipping, rad.
    pub rotation_rad: f64,
}
