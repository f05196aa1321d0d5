//! The physical description of a GelSight contact: layer, material, indenter.
//!
//! These are plain data with units in their names. The protocol schema (in `experiments`)
//! parses user-written quantities and converts them into these types, so nothing here
//! knows about YAML or unit strings.

use crate::{MechanicsError, PronyTerm, check_range};

/// The elastomer pad: a layer bonded to a rigid (acrylic) base, free on top.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layer {
    /// Pad width along the sensor's x axis.
    pub width_mm: f64,
    /// Pad length along the sensor's y axis.
    pub length_mm: f64,
    /// Layer thickness `h`: the length scale of every finite-thickness effect.
    pub thickness_mm: f64,
}

impl Layer {
    /// Validates the dimensions.
    pub fn check(&self) -> Result<(), MechanicsError> {
        check_range("width_mm", self.width_mm, self.width_mm > 0.0, "> 0")?;
        check_range("length_mm", self.length_mm, self.length_mm > 0.0, "> 0")?;
        check_range(
            "thickness_mm",
            self.thickness_mm,
            self.thickness_mm > 0.0,
            "> 0",
        )
    }
}

/// Linear viscoelastic, isotropic elastomer with Coulomb friction against the indenter.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Long-term (relaxed, quasistatic) Young's modulus E∞ in MPa.
    pub youngs_modulus_mpa: f64,
    /// Poisson ratio; silicone elastomers are nearly incompressible (0.49–0.5).
    pub poisson_ratio: f64,
    /// Prony terms: extra modulus `weight · E∞` relaxing with time constant `tau_s`.
    pub prony: Vec<PronyTerm>,
    /// Coulomb friction coefficient between indenter and elastomer.
    pub friction: f64,
}

impl Material {
    /// Validates the parameters; ν = 0.5 exactly is allowed (incompressible limit).
    pub fn check(&self) -> Result<(), MechanicsError> {
        check_range(
            "youngs_modulus_mpa",
            self.youngs_modulus_mpa,
            self.youngs_modulus_mpa > 0.0,
            "> 0",
        )?;
        check_range(
            "poisson_ratio",
            self.poisson_ratio,
            (0.0..=0.5).contains(&self.poisson_ratio),
            "0 to 0.5",
        )?;
        check_range("friction", self.friction, self.friction >= 0.0, ">= 0")?;
        for term in &self.prony {
            term.check()?;
        }
        Ok(())
    }

    /// Long-term shear modulus G∞ = E/(2(1+ν)).
    pub fn shear_modulus_mpa(&self) -> f64 {
        self.youngs_modulus_mpa / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// Plane-strain modulus E* = E/(1−ν²) for a rigid indenter (Johnson §3.4).
    pub fn contact_modulus_mpa(&self) -> f64 {
        self.youngs_modulus_mpa / (1.0 - self.poisson_ratio * self.poisson_ratio)
    }
}

/// The indenters of thesis Fig. 3-11 (acrylic, rigid against the elastomer), plus the
/// lying cylinder that models a grasped can (thesis §6.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Indenter {
    /// Flat-ended circular punch.
    FlatCircle {
        /// Punch diameter.
        diameter_mm: f64,
    },
    /// Flat-ended elliptical punch; axes are full lengths, major along x.
    FlatEllipse {
        /// Full major axis.
        major_mm: f64,
        /// Full minor axis.
        minor_mm: f64,
    },
    /// Flat-ended rectangular punch, width along x.
    FlatRectangle {
        /// Side along x.
        width_mm: f64,
        /// Side along y.
        length_mm: f64,
    },
    /// Flat-ended equilateral triangle.
    FlatTriangle {
        /// Side length.
        side_mm: f64,
    },
    /// Rigid sphere.
    Sphere {
        /// Sphere diameter.
        diameter_mm: f64,
    },
    /// Cylinder lying on the pad with its axis along x (a can in a grasp: its weight pulls
    /// along the axis, the direction the tangential solver loads).
    Cylinder {
        /// Cylinder diameter.
        diameter_mm: f64,
        /// Cylinder length (the contact is clipped to the pad).
        length_mm: f64,
    },
}

impl Indenter {
    /// Validates the dimensions.
    pub fn check(&self) -> Result<(), MechanicsError> {
        let dims: &[(&'static str, f64)] = match self {
            Indenter::FlatCircle { diameter_mm } => &[("diameter_mm", *diameter_mm)],
            Indenter::FlatEllipse { major_mm, minor_mm } => {
                check_range(
                    "minor_mm",
                    *minor_mm,
                    minor_mm <= major_mm,
                    "<= major_mm (the major axis is the longer one)",
                )?;
                &[("major_mm", *major_mm), ("minor_mm", *minor_mm)]
            }
            Indenter::FlatRectangle {
                width_mm,
                length_mm,
            } => &[("width_mm", *width_mm), ("length_mm", *length_mm)],
            Indenter::FlatTriangle { side_mm } => &[("side_mm", *side_mm)],
            Indenter::Sphere { diameter_mm } => &[("diameter_mm", *diameter_mm)],
            Indenter::Cylinder {
                diameter_mm,
                length_mm,
            } => &[("diameter_mm", *diameter_mm), ("length_mm", *length_mm)],
        };
        for (name, v) in dims {
            check_range(name, *v, *v > 0.0, "> 0")?;
        }
        Ok(())
    }

    /// True for punches whose contact area does not change with depth.
    pub fn is_flat(&self) -> bool {
        matches!(
            self,
            Indenter::FlatCircle { .. }
                | Indenter::FlatEllipse { .. }
                | Indenter::FlatRectangle { .. }
                | Indenter::FlatTriangle { .. }
        )
    }

    /// Area of a flat punch's face in mm²; `None` for curved indenters.
    pub fn flat_area_mm2(&self) -> Option<f64> {
        use std::f64::consts::PI;
        match *self {
            Indenter::FlatCircle { diameter_mm } => Some(PI * diameter_mm * diameter_mm / 4.0),
            Indenter::FlatEllipse { major_mm, minor_mm } => Some(PI * major_mm * minor_mm / 4.0),
            Indenter::FlatRectangle {
                width_mm,
                length_mm,
            } => Some(width_mm * length_mm),
            Indenter::FlatTriangle { side_mm } => Some(3f64.sqrt() / 4.0 * side_mm * side_mm),
            Indenter::Sphere { .. } | Indenter::Cylinder { .. } => None,
        }
    }

    /// Largest horizontal extent of the indenter in mm (used for view and travel checks).
    pub fn footprint_mm(&self) -> f64 {
        match *self {
            Indenter::FlatCircle { diameter_mm } | Indenter::Sphere { diameter_mm } => diameter_mm,
            Indenter::FlatEllipse { major_mm, .. } => major_mm,
            Indenter::FlatRectangle {
                width_mm,
                length_mm,
            } => width_mm.hypot(length_mm),
            Indenter::FlatTriangle { side_mm } => side_mm,
            Indenter::Cylinder {
                diameter_mm,
                length_mm,
            } => diameter_mm.max(length_mm),
        }
    }
}

/// The thesis's two sensors, as defaults and test fixtures.
///
/// Geometry is the thesis's (§4.1: the box sensor's 125 × 70 × 4.2 mm pad; §6.2: the portable
/// sensor's 22.6 × 23.4 × 2.0 mm pad). Material values are chosen so dry runs land where the
/// thesis's figures do — the box sphere at 1 mm near the reported 2.1 N, relaxation
/// complete to ≈0.5 % after the 3-minute settles of §4.2 (1–2 minutes on the portable pad,
/// §6.2), shear slipping within the thesis's load ranges. No measured material data exist for
/// these elastomers (spec §3): calibrate them per gel.
pub mod presets {
    use super::{Layer, Material};
    use crate::PronyTerm;

    /// The box sensor's pad.
    pub const BOX_LAYER: Layer = Layer {
        width_mm: 125.0,
        length_mm: 70.0,
        thickness_mm: 4.2,
    };

    /// The portable sensor's pad.
    pub const PORTABLE_LAYER: Layer = Layer {
        width_mm: 22.6,
        length_mm: 23.4,
        thickness_mm: 2.0,
    };

    fn material(e_mpa: f64, prony: &[(f64, f64)]) -> Material {
        Material {
            youngs_modulus_mpa: e_mpa,
            poisson_ratio: 0.49,
            prony: prony
                .iter()
                .map(|&(weight, tau_s)| PronyTerm { weight, tau_s })
                .collect(),
            friction: 0.6,
        }
    }

    /// The box sensor's elastomer: E∞ = 0.25 MPa, ν = 0.49, μ = 0.6, τ = 1.5 / 15 / 60 s.
    pub fn box_material() -> Material {
        material(0.25, &[(0.25, 1.5), (0.20, 15.0), (0.15, 60.0)])
    }

    /// The portable sensor's elastomer: E∞ = 0.15 MPa, ν = 0.49, μ = 0.6, τ = 1 / 10 / 40 s.
    pub fn portable_material() -> Material {
        material(0.15, &[(0.30, 1.0), (0.20, 10.0), (0.10, 40.0)])
    }

    /// Sliding over static friction, the default for both sensors.
    pub const KINETIC_RATIO: f64 = 0.9;
}
