//! A frame of the simulated bench's camera for a contact the caller gives — an indentation
//! depth, a stage shear and twist, and where the contact sits in the view — without running
//! a protocol: for a robot loop's tests, a tracker's, or a figure. The frame is drawn as the
//! simulated camera draws its frames during a dry run (the same contact model and the same
//! renderer), and comes with the exact centre of every marker.

use mechanics::response::{ContactModel, ModelSpec, State};

use super::plant::PlantSpec;
use super::render::{Renderer, SurfaceView};

/// The contact to draw.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactPose {
    /// Indentation depth, mm.
    pub depth_mm: f64,
    /// How far the indenter has been moved along the image's x after pressing, mm: the
    /// stage displacement of the thesis's shear experiments (§3.3), applied monotonically
    /// from the pressed state (the virgin branch of the shear backbone).
    pub shear_mm: f64,
    /// How far the indenter has been turned about the normal after pressing, degrees (the
    /// virgin branch of the twist backbone).
    pub twist_deg: f64,
    /// Where the contact's centre sits in the view, from the view's centre (x right, y
    /// down), mm.
    pub centre_mm: (f64, f64),
}

/// One frame: RGB pixels (row-major, 3 bytes a pixel) and the true centre of every marker,
/// px (pixel (i, j) centred at (i, j)).
#[derive(Debug, Clone, PartialEq)]
pub struct ContactFrame {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// RGB pixels.
    pub rgb: Vec<u8>,
    /// Where each printed marker is, px.
    pub markers_px: Vec<[f64; 2]>,
    /// The contact's normal force once the gel has relaxed (its long-term elastic force at
    /// this depth), N; 0 at rest.
    pub normal_force_n: f64,
    /// The contact's effective radius √(A/π), mm; 0 at rest.
    pub contact_radius_mm: f64,
    /// The tangential force the contact carries at the pose's shear, N (along x).
    pub shear_n: f64,
    /// The twisting moment the contact carries at the pose's twist, N·mm.
    pub torque_nmm: f64,
    /// The fraction of the contact area that sticks under the pose's shear (1 before any
    /// shear, 0 once the contact slides); `None` with no contact.
    pub stick_fraction_shear: Option<f64>,
    /// The same under the pose's twist.
    pub stick_fraction_twist: Option<f64>,
}

/// Draws frames of one sensor and indenter at one camera resolution.
pub struct ContactCamera {
    model: ContactModel,
    renderer: Renderer,
    size: (u32, u32),
    /// The deepest indentation the model was built for, mm.
    max_depth_mm: f64,
    /// The shear and twist backbones were built.
    tangential: bool,
}

impl ContactCamera {
    /// A camera of `width × height` px on the sensor of `spec` (from
    /// `experiments::protocol::plant_spec` of a loaded protocol), pressing only: shear and
    /// twist are drawn as zero. Builds the contact model once (the costly part, as when a
    /// run opens its simulated bench).
    pub fn new(spec: &PlantSpec, width: u32, height: u32) -> Result<Self, String> {
        Self::build(spec, width, height, false)
    }

    /// As [`Self::new`], with the shear and twist backbones built too.
    pub fn with_shear_and_twist(spec: &PlantSpec, width: u32, height: u32) -> Result<Self, String> {
        Self::build(spec, width, height, true)
    }

    fn build(spec: &PlantSpec, width: u32, height: u32, tangential: bool) -> Result<Self, String> {
        if !(16..=8192).contains(&width) || !(16..=8192).contains(&height) {
            return Err(format!(
                "a {width}×{height} px camera: cameras deliver 16 to 8192 pixels a side"
            ));
        }
        let model = ContactModel::build_stored(
            ModelSpec {
                contact: spec.contact.clone(),
                max_depth_mm: spec.max_depth_mm,
                shear: tangential,
                twist: tangential,
                field_view_mm: Some((spec.view_width_mm, spec.view_height_mm)),
                pressing_friction: true,
                quality: spec.quality,
            },
            tablecache::store(),
        )
        .map_err(|e| e.to_string())?;
        Ok(Self {
            model,
            renderer: Renderer::new(spec, width, height),
            size: (width, height),
            max_depth_mm: spec.max_depth_mm,
            tangential,
        })
    }

    /// Millimetres per pixel of the view.
    pub fn mm_per_px(&self) -> f64 {
        self.renderer.mm_per_px()
    }

    /// The gel at rest: no contact.
    pub fn at_rest(&self, seq: u64) -> ContactFrame {
        self.frame_of(None, seq)
    }

    /// The frame of `contact`; `seq` picks the sensor noise (each frame number its own). An
    /// error names a contact the model cannot draw (deeper than the spec's deepest
    /// indentation, a shear or twist on a pressing-only camera, a value not finite).
    pub fn frame(&mut self, contact: &ContactPose, seq: u64) -> Result<ContactFrame, String> {
        self.frame_and_surface(contact, seq, false).map(|(f, _)| f)
    }

    /// [`Self::frame`] and the gel surface's depth at each pixel (mm, into the gel,
    /// row-major): the truth a shape reading of the frame is checked against.
    pub fn frame_with_surface(
        &mut self,
        contact: &ContactPose,
        seq: u64,
    ) -> Result<(ContactFrame, Vec<f32>), String> {
        self.frame_and_surface(contact, seq, true)
    }

    fn frame_and_surface(
        &mut self,
        contact: &ContactPose,
        seq: u64,
        with_surface: bool,
    ) -> Result<(ContactFrame, Vec<f32>), String> {
        let values = [
            contact.depth_mm,
            contact.shear_mm,
            contact.twist_deg,
            contact.centre_mm.0,
            contact.centre_mm.1,
        ];
        if values.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "the contact {contact:?} has a value that is not finite"
            ));
        }
        if !(0.0..=self.max_depth_mm).contains(&contact.depth_mm) {
            return Err(format!(
                "depth {} mm: the contact model was built for depths 0 to {:.3} mm (the spec's \
                 `max_depth_mm`; raise it to draw deeper)",
                contact.depth_mm, self.max_depth_mm
            ));
        }
        if !self.tangential && (contact.shear_mm != 0.0 || contact.twist_deg != 0.0) {
            return Err(format!(
                "a shear of {} mm and a twist of {}° on a camera built for pressing only: \
                 build it with `ContactCamera::with_shear_and_twist`",
                contact.shear_mm, contact.twist_deg
            ));
        }
        let (shear_n, stick_shear) =
            self.tangential_at(contact.depth_mm, contact.shear_mm, false)?;
        let twist_rad = contact.twist_deg.to_radians();
        let (torque_nmm, stick_twist) = self.tangential_at(contact.depth_mm, twist_rad, true)?;
        let state = State {
            depth_mm: contact.depth_mm,
            shear_n,
            torque_nmm,
        };
        let field = self
            .model
            .field(state)
            .ok_or_else(|| format!("the contact model cannot draw {contact:?}"))?;
        let surface = SurfaceView {
            field,
            centre_mm: contact.centre_mm,
            rotation_rad: 0.0,
        };
        let depth = if with_surface {
            self.renderer.surface_depth_mm(&surface)
        } else {
            Vec::new()
        };
        let mut frame = self.frame_of(Some(&surface), seq);
        frame.normal_force_n = self.model.normal_force_n(contact.depth_mm);
        frame.contact_radius_mm = self.model.contact_radius_mm(contact.depth_mm);
        frame.shear_n = shear_n;
        frame.torque_nmm = torque_nmm;
        frame.stick_fraction_shear = stick_shear;
        frame.stick_fraction_twist = stick_twist;
        Ok((frame, depth))
    }

    /// The force (or moment) and stick fraction at displacement `x` (mm, or rad when
    /// `twist`) on the virgin branch of the contact's backbone at `depth_mm` (Yuan 2014,
    /// §3.3: the stage moves, the contact's partial slip sets the force). `(0, None)` with no
    /// contact; `(0, Some(1))` before any displacement.
    fn tangential_at(
        &mut self,
        depth_mm: f64,
        x: f64,
        twist: bool,
    ) -> Result<(f64, Option<f64>), String> {
        if depth_mm <= 0.0 {
            return Ok((0.0, None));
        }
        if x == 0.0 {
            return Ok((0.0, Some(1.0)));
        }
        let curve = match twist {
            true => self.model.twist_curve(depth_mm),
            false => self.model.shear_curve(depth_mm),
        };
        let (backbone, stick) =
            curve.ok_or_else(|| format!("no tangential table at depth {depth_mm} mm"))?;
        let fraction = mechanics::response::stick_at(&backbone, &stick, x);
        Ok((backbone.force(x), Some(fraction.clamp(0.0, 1.0))))
    }

    fn frame_of(&self, surface: Option<&SurfaceView>, seq: u64) -> ContactFrame {
        let (rgb, markers_px) = self.renderer.render(surface, seq);
        ContactFrame {
            width: self.size.0,
            height: self.size.1,
            rgb,
            markers_px,
            normal_force_n: 0.0,
            contact_radius_mm: 0.0,
            shear_n: 0.0,
            torque_nmm: 0.0,
            stick_fraction_shear: None,
            stick_fraction_twist: None,
        }
    }
}
