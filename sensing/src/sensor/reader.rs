//! A sensor file made ready to read frames: the layout, the model, and for the traction
//! method the layer's kernels (computed once per sensor, a few milliseconds).

use analysis::force_sensor::memory::Memory;
use analysis::force_sensor::ridge::LinearModel;
use analysis::force_sensor::traction::{self, TractionKernel, TractionMap};
use analysis::force_sensor::{Layout, TRACTION_FEATURES_ROUND};

use super::file::{METHOD_SCALE, METHOD_TRACTION, SensorFile, TractionSettings, View};
use analysis::force_sensor::scale::ScaleBasis;
use tracking::field::MarkerField;

/// A calibrated sensor ready to read frames.
pub struct Reader {
    /// The camera's view of the gel.
    pub view: View,
    /// What the calibration saw (absent in files before version 4).
    envelope: Option<super::file::Envelope>,
    /// Its error on indenters left out of the fit.
    unseen: Option<super::file::UnseenShape>,
    /// The calibrated range of each channel.
    ranges: std::collections::BTreeMap<String, [f64; 2]>,
    /// The marker layout.
    pub layout: Layout,
    /// The per-channel model.
    pub model: LinearModel,
    traction: Option<(TractionKernel, TractionSettings)>,
    /// Whether the traction model reads the elongation term (files calibrated on
    /// elongated contacts).
    elongation: bool,
    scale: Option<ScaleBasis>,
    prony: Option<mechanics::Prony>,
    /// The Fz range the calibration's force sensor saw, N.
    fz_range_n: Option<[f64; 2]>,
}

/// One frame read: the model's features, the share of markers measured, and the traction
/// map where the method makes one.
pub struct Reading {
    /// Features in the sensor's order.
    pub features: Vec<f64>,
    /// Share of the layout's markers measured in the frame.
    pub measured_share: f64,
    /// The traction map (traction method, frames with a contact region).
    pub map: Option<TractionMap>,
}

impl Reader {
    /// Prepares `file` for reading.
    pub fn new(file: &SensorFile) -> Self {
        let traction = (file.method == METHOD_TRACTION)
            .then_some(file.traction)
            .flatten()
            .map(|t| (kernel_for(file, &t), t));
        let layout = file.layout();
        // A sensor file's check has built this basis once: it is there for a scale fit.
        let scale = (file.method == METHOD_SCALE)
            .then_some(file.scale.as_ref())
            .flatten()
            .and_then(|s| super::scale::basis(s, &layout));
        Self {
            view: file.view.clone(),
            envelope: file.envelope.clone(),
            unseen: file.unseen_shape.clone(),
            ranges: file.ranges.clone(),
            layout,
            model: file.model(),
            traction,
            elongation: file.features.len() > TRACTION_FEATURES_ROUND.len()
                && file.method == METHOD_TRACTION,
            scale,
            prony: file.prony(),
            fz_range_n: file.ranges.get("fz_n").copied(),
        }
    }

    /// A fresh memory of the gel's load history for a recording, when the sensor knows the
    /// gel's relaxation: its Fz is then the hereditary integral of the field's elastic force
    /// ([`analysis::force_sensor::memory`]), read frame by frame in time order.
    pub fn memory(&self) -> Option<Memory> {
        self.prony.clone().map(Memory::new)
    }

    /// The Fz range the sensor was calibrated over (its force sensor's readings), N.
    pub fn fz_range_n(&self) -> Option<[f64; 2]> {
        self.fz_range_n
    }

    /// Reads one frame's `field` with its contact region, its markers matched to the layout
    /// by `map`.
    pub fn read(
        &self,
        field: &MarkerField,
        contact: Option<super::history::Region>,
        map: &[Option<usize>],
    ) -> Reading {
        let (u, measured_share) = self.layout.displacements_mm(field, map);
        if let Some(basis) = &self.scale {
            return Reading {
                features: basis.features(&u),
                measured_share,
                map: None,
            };
        }
        match &self.traction {
            None => Reading {
                features: self.layout.features(&u).to_vec(),
                measured_share,
                map: None,
            },
            Some((kernel, t)) => {
                let tmap = traction_map(&self.layout, kernel, t, &u, contact, Some(t.lambda));
                Reading {
                    features: traction_features(tmap.as_ref(), contact.as_ref(), self.elongation),
                    measured_share,
                    map: tmap,
                }
            }
        }
    }
}

/// One frame's wrench: values and standard uncertainties per channel (Fx, Fy, Fz, Tz), and
/// the frame judged against the calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Wrench {
    /// Fx, Fy, Fz (N), Tz (N·mm).
    pub value: Vec<f64>,
    /// Their standard uncertainties, widened where the frame is outside the calibration.
    pub sd: Vec<f64>,
    /// Why the frame is outside the calibration, and the share of its contact in view.
    pub judgement: super::envelope::Judgement,
}

impl Reader {
    /// The wrench of a frame `reading` with its contact `region`, through the gel's load
    /// `history` at `t_ns`: the model's reading, corrected for a contact running beyond
    /// the view where its geometry says how far, the hereditary Fz, and uncertainties that
    /// cover what the calibration did not see ([`super::envelope`]).
    pub fn wrench(
        &self,
        reading: &Reading,
        region: Option<super::history::Region>,
        history: &mut super::history::LoadHistory,
        t_ns: u64,
    ) -> Wrench {
        let (mut value, mut sd) = self.model.predict(&reading.features);
        let mut judgement = match &self.envelope {
            Some(e) => e.judge(region.as_ref(), &reading.features, &self.view),
            None => super::envelope::Judgement {
                outside: Vec::new(),
                in_view: 1.0,
                corrected: false,
            },
        };
        // The traction map's support already runs past the view's edge with the contact's
        // ellipse: it reads the part beyond the view itself.
        if self.traction.is_some() {
            judgement.corrected = false;
        }
        super::envelope::correct(&mut value, &judgement);
        history.wrench(t_ns, &mut value, region);
        if self.envelope.is_some() {
            super::envelope::widen(
                &value,
                &mut sd,
                &mut judgement,
                self.unseen.as_ref(),
                &self.ranges,
            );
        }
        Wrench {
            value,
            sd,
            judgement,
        }
    }
}

/// A traction map's features ([`analysis::force_sensor::TRACTION_FEATURES`]): its four
/// integrals, and with `elongated` the normal one times the contact `region`'s elongation;
/// zeros without a map (no contact).
pub(crate) fn traction_features(
    map: Option<&TractionMap>,
    region: Option<&super::history::Region>,
    elongated: bool,
) -> Vec<f64> {
    let mut f = map.map_or(vec![0.0; 4], |m| m.wrench.to_vec());
    if elongated {
        f.push(f[2] * super::gather::elongation_of(region));
    }
    f
}

/// The layer's kernels for a sensor's view.
pub(crate) fn kernel_for(file: &SensorFile, t: &TractionSettings) -> TractionKernel {
    kernel_from_view(&file.view, t)
}

/// The layer's kernels reaching across `view`'s diagonal.
pub(crate) fn kernel_from_view(view: &View, t: &TractionSettings) -> TractionKernel {
    let reach = (view.width_px as f64).hypot(view.height_px as f64) * view.mm_per_px;
    TractionKernel::new(t.thickness_mm, t.kernel_dx_mm, reach)
}

/// The traction map of displacements `u_mm` at the layout's markers, on `support` times the
/// contact's moment-equivalent ellipse (its equivalent disc where the region has no recorded
/// moments, or the sensor's support was chosen for the disc); `None` without contact.
pub(crate) fn traction_map(
    layout: &Layout,
    kernel: &TractionKernel,
    t: &TractionSettings,
    u_mm: &[[f64; 2]],
    contact: Option<super::history::Region>,
    lambda: Option<f64>,
) -> Option<TractionMap> {
    let region = contact?;
    let s = layout.mm_per_px;
    let to_mm = |p: [f64; 2]| {
        [
            (p[0] - layout.centre_px[0]) * s,
            (p[1] - layout.centre_px[1]) * s,
        ]
    };
    let (c_px, r_px) = (region.centroid_px, region.radius_px);
    // A sensor whose support was chosen for the equal-area disc (before version 3) reads
    // with the disc, whatever the region's moments.
    let cells = match region.second_moments_px2.filter(|_| t.ellipse) {
        Some(m) => traction::ellipse_cells(
            to_mm(c_px),
            [m[0] * s * s, m[1] * s * s, m[2] * s * s],
            t.support,
            t.cell_mm,
            t.cell_mm,
        ),
        None => traction::disc_cells(to_mm(c_px), r_px * s * t.support, t.cell_mm),
    };
    let markers: Vec<[f64; 2]> = layout.reference_px.iter().map(|p| to_mm(*p)).collect();
    traction::solve(kernel, &markers, u_mm, &cells, t.cell_mm, lambda)
}
