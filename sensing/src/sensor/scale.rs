//! The scale fit's reference fields: the calibration's contact under unit loads, from the
//! bonded layer model of the first calibration run's protocol, at the layout's markers
//! ([`analysis::force_sensor::scale`]).

use analysis::field_force::reference_at_markers;
use analysis::force_sensor::Layout;
use analysis::force_sensor::scale::ScaleBasis;
use mechanics::response::{ContactModel, ModelSpec, State};
use simbench::PlantSpec;

use serde::{Deserialize, Serialize};

/// The reference fields of the scale fit: the calibration's contact under unit loads, at
/// the layout's markers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleSettings {
    /// The contact the fields are of (the first calibration run's indenter).
    pub indenter: String,
    /// Depth of the reference contact, mm.
    pub reference_depth_mm: f64,
    /// Its contact radius, mm (where the reliability weights change).
    pub contact_radius_mm: f64,
    /// Normal, x shear, y shear and twist fields, each mm at every layout marker.
    pub fields: Vec<Vec<[f64; 2]>>,
}

/// Depth of the reference contact, as a fraction of the thickness: mid-range of the
/// protocols' normal steps (box to 20 %, portable to 30 %).
const REFERENCE_DEPTH: f64 = 0.1;

/// Tangential reference loads as a fraction of the friction limit μP: well inside full
/// stick, where the layer's response is linear in the load.
const TANGENTIAL_SHARE: f64 = 0.2;

/// The reference fields of `spec`'s contact at `layout`'s markers.
pub(crate) fn reference_fields(spec: &PlantSpec, layout: &Layout) -> Result<ScaleSettings, String> {
    let contact = spec.contact.clone();
    let h = contact.layer.thickness_mm;
    let depth = REFERENCE_DEPTH * h;
    let mut model = ContactModel::build(ModelSpec {
        contact: contact.clone(),
        max_depth_mm: depth * 1.05,
        shear: true,
        twist: true,
        field_view_mm: Some((spec.view_width_mm, spec.view_height_mm)),
        pressing_friction: false,
        quality: spec.quality,
    })
    .map_err(|e| format!("the reference contact's model failed: {e}"))?;
    let p_n = model.normal_force_n(depth);
    let a_mm = model.contact_radius_mm(depth);
    let mu = contact.material.friction;
    let q_n = TANGENTIAL_SHARE * mu * p_n;
    // A disc's torsional limit is (2/3)μPa; the strip's and the others' are of that order.
    let t_nmm = TANGENTIAL_SHARE * mu * p_n * a_mm * 2.0 / 3.0;
    let state = |shear_n: f64, torque_nmm: f64| State {
        depth_mm: depth,
        shear_n,
        torque_nmm,
    };
    let at = |f: &mechanics::response::Field, rotation_rad: f64| -> Vec<[f64; 2]> {
        reference_at_markers(
            f,
            &layout.reference_px,
            layout.centre_px,
            layout.mm_per_px,
            rotation_rad,
        )
        .into_iter()
        .map(|u| [u[0] * layout.mm_per_px, u[1] * layout.mm_per_px])
        .collect()
    };
    let missing = || "the reference contact's model has no fields".to_string();
    let normal = model.field(state(0.0, 0.0)).ok_or_else(missing)?;
    let sheared = model.field(state(q_n, 0.0)).ok_or_else(missing)?;
    let twisted = model.field(state(0.0, t_nmm)).ok_or_else(missing)?;
    let un = at(&normal, 0.0);
    let minus = |a: Vec<[f64; 2]>, scale: f64| -> Vec<[f64; 2]> {
        a.iter()
            .zip(&un)
            .map(|(v, n)| [(v[0] - n[0]) / scale, (v[1] - n[1]) / scale])
            .collect()
    };
    // Per unit load: the normal field per N, the shears per N, the twist per N·mm.
    let fields = vec![
        un.iter().map(|v| [v[0] / p_n, v[1] / p_n]).collect(),
        minus(at(&sheared, 0.0), q_n),
        // The y shear: the x shear's field turned a quarter turn about the contact's centre
        // (the contact's own asymmetry in y is second order for the fit).
        {
            let un_turned = at(&normal, std::f64::consts::FRAC_PI_2);
            at(&sheared, std::f64::consts::FRAC_PI_2)
                .iter()
                .zip(&un_turned)
                .map(|(v, n)| [(v[0] - n[0]) / q_n, (v[1] - n[1]) / q_n])
                .collect()
        },
        minus(at(&twisted, 0.0), t_nmm),
    ];
    Ok(ScaleSettings {
        indenter: format!("{:?}", contact.indenter),
        reference_depth_mm: depth,
        contact_radius_mm: a_mm,
        fields,
    })
}

/// The fit's basis for `settings` on `layout`.
pub(crate) fn basis(settings: &ScaleSettings, layout: &Layout) -> Option<ScaleBasis> {
    let s = layout.mm_per_px;
    let markers: Vec<[f64; 2]> = layout
        .reference_px
        .iter()
        .map(|p| {
            [
                (p[0] - layout.centre_px[0]) * s,
                (p[1] - layout.centre_px[1]) * s,
            ]
        })
        .collect();
    let f = &settings.fields;
    if f.len() != 4 {
        return None;
    }
    ScaleBasis::new(
        [f[0].clone(), f[1].clone(), f[2].clone(), f[3].clone()],
        &markers,
        settings.contact_radius_mm,
    )
}
