//! One frame through the chain: colour change → touched region → slopes → height map,
//! levelled on the untouched gel; and the contact's statistics from the height.

use crate::ShapeError;
use crate::farfield;
use crate::frame::{Rgb, colour_change};
use crate::markers;
use crate::mask;
use crate::model::SlopeMap;
use crate::poisson::Integrator;

/// Depth (mm) from which a pixel counts as in contact in [`DepthStats`]: the largest height
/// the untouched gel (beyond 2.5 contact radii) reads on the median GelSight Mini ball press,
/// 0.028 mm, about five times its standard deviation (docs/explanation/shape.md).
pub const CONTACT_DEPTH_MM: f64 = 0.03;

/// The reader of height maps for one sensor: its slope model, background and scale; it keeps
/// its buffers between frames.
#[derive(Debug)]
pub struct Depth {
    map: SlopeMap,
    background: Vec<u8>,
    mm_per_px: f64,
    integrator: Integrator,
    change: Vec<f32>,
    masker: mask::Masker,
    touched: Vec<bool>,
    far: Vec<bool>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    depth_px: Vec<f32>,
    height_mm: Vec<f32>,
    /// The background's marker ink, where the gel has markers (`None` on a markerless gel:
    /// fewer than 0.2 % of the background's pixels read as ink).
    background_ink: Option<Vec<bool>>,
    ink: Vec<bool>,
    buffers: [Vec<f32>; 3],
}

/// A frame's contact read from its height map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthStats {
    /// The deepest point, mm (positive into the gel).
    pub max_depth_mm: f64,
    /// Area deeper than [`CONTACT_DEPTH_MM`], mm².
    pub contact_area_mm2: f64,
    /// Depth-weighted centroid of that area, px (NaN without contact).
    pub centroid_px: [f64; 2],
    /// Volume pressed below the surface within the touched region, mm³.
    pub volume_mm3: f64,
}

impl Depth {
    /// A reader for frames the size of `background` (the unpressed gel, taken in the same
    /// session as the frames), `mm_per_px` the image scale.
    pub fn new(map: SlopeMap, background: Rgb<'_>, mm_per_px: f64) -> Result<Self, ShapeError> {
        background.same_size(map.width, map.height, "model was prepared for")?;
        let n = map.width * map.height;
        let mut buffers: [Vec<f32>; 3] = Default::default();
        let background_ink = markers::background_ink(&background, &mut buffers);
        let mut map = map;
        map.light(&background);
        Ok(Self {
            background_ink,
            ink: vec![false; n],
            buffers,
            integrator: Integrator::new(map.width, map.height),
            map,
            background: background.pixels.to_vec(),
            mm_per_px,
            change: Vec::with_capacity(3 * n),
            masker: mask::Masker::default(),
            touched: vec![false; n],
            far: vec![false; n],
            gx: vec![0.0; n],
            gy: vec![0.0; n],
            depth_px: vec![0.0; n],
            height_mm: vec![0.0; n],
        })
    }

    /// The frame size.
    pub fn size(&self) -> (usize, usize) {
        (self.map.width, self.map.height)
    }

    /// Reads `frame`'s height map: mm, row-major, positive out of the gel (a press reads
    /// negative), 0 on the untouched gel.
    pub fn height(&mut self, frame: Rgb<'_>) -> Result<&[f32], ShapeError> {
        let (w, h) = self.size();
        frame.same_size(w, h, "background is")?;
        let background = Rgb {
            width: w,
            height: h,
            pixels: &self.background,
        };
        colour_change(&frame, &background, &mut self.change);
        let inked = self.mark_markers(&frame);
        self.masker
            .touched(&self.change, (w, h), &mut self.touched, &mut self.far);
        self.map
            .slopes(&self.change, &self.touched, &mut self.gx, &mut self.gy);
        if inked {
            for (hole, t) in self.ink.iter_mut().zip(&self.touched) {
                *hole &= *t;
            }
            markers::fill(&mut self.gx, &self.ink, w, h, 3, &mut self.buffers);
            markers::fill(&mut self.gy, &self.ink, w, h, 3, &mut self.buffers);
        }
        self.integrator
            .integrate(&self.gx, &self.gy, &mut self.depth_px);
        farfield::level(&mut self.depth_px, &self.far, w, h);
        let s = self.mm_per_px as f32;
        for (o, d) in self.height_mm.iter_mut().zip(&self.depth_px) {
            *o = -d * s;
        }
        Ok(&self.height_mm)
    }

    /// On a gel with markers, marks the ink of `frame` and of the background in `self.ink`
    /// and takes it out of the colour change; whether there was any.
    fn mark_markers(&mut self, frame: &Rgb<'_>) -> bool {
        let Some(bg_ink) = &self.background_ink else {
            return false;
        };
        let (w, h) = self.size();
        self.ink.copy_from_slice(bg_ink);
        markers::mark_ink(frame.pixels, w, h, &mut self.ink, &mut self.buffers);
        for (i, ink) in self.ink.iter().enumerate() {
            if *ink {
                self.change[3 * i..3 * i + 3].fill(0.0);
            }
        }
        true
    }

    /// The last frame's depth in pixels (positive into the gel) and its slopes, for scoring.
    pub fn last_depth_px(&self) -> (&[f32], &[f32], &[f32]) {
        (&self.depth_px, &self.gx, &self.gy)
    }

    /// The last frame's contact statistics.
    pub fn stats(&self) -> DepthStats {
        let (w, _) = self.size();
        let px_area = self.mm_per_px * self.mm_per_px;
        let (mut max, mut area, mut volume) = (0.0f64, 0.0, 0.0);
        let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
        for (i, hgt) in self.height_mm.iter().enumerate() {
            let d = -(*hgt as f64);
            max = max.max(d);
            if self.touched[i] && d > 0.0 {
                volume += d * px_area;
            }
            if d >= CONTACT_DEPTH_MM {
                area += px_area;
                sx += d * (i % w) as f64;
                sy += d * (i / w) as f64;
                sw += d;
            }
        }
        DepthStats {
            max_depth_mm: max,
            contact_area_mm2: area,
            centroid_px: if sw > 0.0 {
                [sx / sw, sy / sw]
            } else {
                [f64::NAN; 2]
            },
            volume_mm3: volume,
        }
    }
}
