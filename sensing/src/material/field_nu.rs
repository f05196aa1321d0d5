//! Poisson's ratio from the marker field of flat-punch pressing runs.
//!
//! A flat circular punch held at depth δ on the bonded layer moves the surface around it by
//! δ·U(r; ν). The field is set by the depth, not by the modulus: a viscoelastic gel of
//! constant ν keeps its field while the force relaxes (the correspondence principle, Lee &
//! Radok 1960), so the field against the depth tells ν alone — from one run, where the
//! force record needs two punch sizes ([`super::poisson`]). Near incompressibility it moves
//! fast with ν: around the box's 9.5 mm punch u_r(1.5a)/δ is 0.254 at ν 0.47, 0.319 at
//! 0.49 and 0.337 at 0.495, about 1.2 % per 0.001 of ν against the force's 0.6 % (which
//! also moves with E), and the two box punches' force ratio's 0.15 % (BENCHMARKS.md,
//! "Poisson's ratio from the marker field").
//!
//! Each held loading step's last frame gives the markers' radial displacement about the
//! punch's centre (where the pressing field radiates from) at their distance r; the model's
//! U(r; ν) comes from the run's own contact model (its layer, its punch, pressed as its rig
//! presses) on a grid of ν, interpolated between; ν minimises the squared misfit over every
//! step and marker, its uncertainty from the misfit's curvature scaled by the residual
//! spread, with [`SD_FLOOR`] in quadrature. Only markers from 1.15a to 2a count: nearer the
//! edge the field's steep rise is blurred by the markers' size and the centre's error;
//! farther out the field is small. On a small pad 2a reaches toward its free sides, where the
//! infinite layer's field is off (the portable pad's by up to 7 % at 1.25a and more beyond;
//! docs/explanation/simulated-bench.md, "Finite pads"): the fit says so in its provenance ([`FieldNu::near_sides`]).
//!
//! What it rests on: the field of the pressing model the rig names. A punch face that sticks
//! (the default; `contact: {pressing_friction: false}` in the rig file for a frictionless one)
//! moves the field outside it by 9–26 % against a frictionless one, which would read as about
//! 0.01–0.02 of ν: a real bench names how its punch presses in its rig file's `contact:`.

use mechanics::response::{ContactModel, ModelSpec, State};
use tracking::field::decompose;

use crate::run_data::RunData;

/// ν values the model's field is first computed at, interpolated linearly between: where
/// to look. The answer comes from the model's own fields about it ([`REFINE`]).
const NU_GRID: [f64; 5] = [0.40, 0.45, 0.47, 0.485, 0.4995];

/// The annulus whose markers count, in punch radii.
const ANNULUS: (f64, f64) = (1.15, 2.0);

/// Radial samples of the model's field across the annulus.
const R_SAMPLES: usize = 64;

/// ν found to this: well inside its uncertainty from the markers' noise (a few 10⁻⁵ on a
/// dry run), each step a sum over the readings (microseconds).
const NU_TOL: f64 = 1e-7;

/// Least markers × steps for a fit.
const MIN_POINTS: usize = 12;

/// Added in quadrature to ν's uncertainty from the markers' noise: what the dry runs show
/// the fit's own systematic error to be (0.00005–0.00014 off on the box and portable pads,
/// where the noise alone said ±0.00001–0.00003; BENCHMARKS.md, "Poisson's ratio from the
/// marker field"). A real bench's — its pressing model, its pad's sides, its image scale —
/// is larger and not in it.
pub(super) const SD_FLOOR: f64 = 2e-4;

/// One run's field record: per held loading step, its depth past contact and its markers'
/// (distance from the punch's centre, radial displacement), mm.
pub(super) struct FieldRecord {
    /// The punch's radius, mm.
    pub(super) a_mm: f64,
    /// (depth, [(r, u_r)]) per step.
    pub(super) steps: Vec<(f64, Vec<(f64, f64)>)>,
    /// The run's contact model at unit modulus, its field over the view.
    pub(super) spec: ModelSpec,
}

/// ν from the fields.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FieldNu {
    /// ν.
    pub(super) nu: f64,
    /// Its standard uncertainty (from the misfit's curvature, scaled by the residual
    /// spread: the markers' noise, not the model's error).
    pub(super) sd: f64,
    /// How many runs and marker readings told it.
    pub(super) runs: usize,
    /// Marker readings (markers × steps).
    pub(super) points: usize,
    /// RMS misfit of the radial displacement at ν, µm.
    pub(super) rms_um: f64,
    /// The annulus reaches within two layer thicknesses of a pad's free side on some run.
    pub(super) near_sides: bool,
    /// The annulus, in punch radii.
    pub(super) annulus: (f64, f64),
}

/// The field record of a flat circular punch's pressing run with frames: its held steps on
/// `axis` that press (loading steps and moves to a depth) with their last frame, depths past
/// the contact offset `offset_mm`, up to the first step that goes shallower or follows a
/// step on another axis (after a shear the field is not the pressing's alone, and a gel
/// unloaded faster than it recovers may leave the face). `Err` says why there is none.
pub(super) fn field_record(
    data: &RunData,
    spec: &ModelSpec,
    view_mm: (f64, f64),
    axis: &str,
    offset_mm: f64,
) -> Result<FieldRecord, String> {
    let mechanics::Indenter::FlatCircle { diameter_mm } = spec.contact.indenter else {
        return Err("its indenter is not a flat circular punch".into());
    };
    let a_mm = 0.5 * diameter_mm;
    let (w, h) = data
        .frame_size
        .ok_or("the size of its frames is unknown (no readable first frame)")?;
    let mm_per_px = (view_mm.0 / w as f64).max(view_mm.1 / h as f64);
    let mut steps: Vec<(f64, tracking::field::MarkerField)> = Vec::new();
    let mut last_depth = f64::NEG_INFINITY;
    for s in &data.steps {
        if s.axis != axis {
            if !steps.is_empty() {
                break;
            }
            continue;
        }
        let Some(pos) = s.position else { continue };
        let depth = pos - offset_mm;
        if depth < last_depth || !(s.phase == "load" || s.phase == "move") {
            break;
        }
        last_depth = depth;
        if depth <= 0.0 {
            continue;
        }
        if let Some(f) = data
            .last_frame_of(s.step)
            .and_then(|fr| crate::run_data::frame_field(data, fr))
        {
            steps.push((depth, f));
        }
    }
    let deepest = steps
        .last()
        .ok_or("no pressing step past the contact has a tracked frame")?;
    let centre = decompose::radiating_centre(&deepest.1)
        .ok_or("its deepest step's field does not radiate from a centre")?;
    let record: Vec<(f64, Vec<(f64, f64)>)> = steps
        .iter()
        .filter_map(|(depth, f)| {
            let pts: Vec<(f64, f64)> = f
                .measured_ids()
                .filter_map(|i| radial(f.reference_px[i], f.displacement_px[i], centre, mm_per_px))
                .filter(|(r, _)| (ANNULUS.0 * a_mm..=ANNULUS.1 * a_mm).contains(r))
                .collect();
            (!pts.is_empty()).then_some((*depth, pts))
        })
        .collect();
    if record.is_empty() {
        return Err(format!(
            "no tracked marker lies between {} and {} punch radii of the punch's centre",
            ANNULUS.0, ANNULUS.1
        ));
    }
    let mut spec = spec.clone();
    spec.field_view_mm = Some(view_mm);
    Ok(FieldRecord {
        a_mm,
        steps: record,
        spec,
    })
}

/// A marker's distance from `centre_px` and its displacement along that radius, both in mm;
/// `None` at the centre itself or for a non-finite displacement.
fn radial(
    reference_px: [f64; 2],
    displacement_px: [f64; 2],
    centre_px: [f64; 2],
    mm_per_px: f64,
) -> Option<(f64, f64)> {
    let (dx, dy) = (
        reference_px[0] - centre_px[0],
        reference_px[1] - centre_px[1],
    );
    let r_px = dx.hypot(dy);
    if r_px <= 0.0 {
        return None;
    }
    let ur = (displacement_px[0] * dx + displacement_px[1] * dy) / r_px * mm_per_px;
    ur.is_finite().then_some((r_px * mm_per_px, ur))
}

/// The model's radial field per mm of depth on [`ANNULUS`] at each of `nus`, two at a time
/// (each is a contact model's build and first field, one to a few seconds on the portable
/// pad; two threads took a portable fit from 24 to 15 s: BENCHMARKS.md, "Poisson's ratio
/// from the marker field").
fn profiles(rec: &FieldRecord, nus: &[f64]) -> Option<Vec<Vec<f64>>> {
    let half = nus.len().div_ceil(2);
    let (a, b) = nus.split_at(half);
    let (pa, pb) = std::thread::scope(|s| {
        let t = s.spawn(|| profiles_one_by_one(rec, b));
        let pa = profiles_one_by_one(rec, a);
        (pa, t.join().ok().flatten())
    });
    let mut all = pa?;
    all.extend(pb?);
    Some(all)
}

/// [`profiles`] for each record, computed once for records of one punch on one layer seen
/// in one view (a pressing run and a shear run's preload with the same punch share them).
fn profiles_all(records: &[FieldRecord], nus: &[f64]) -> Option<Vec<Vec<Vec<f64>>>> {
    let key = |r: &FieldRecord| {
        let mut s = r.spec.clone();
        s.max_depth_mm = 0.0;
        s
    };
    let mut done: Vec<(ModelSpec, Vec<Vec<f64>>)> = Vec::new();
    let mut out = Vec::with_capacity(records.len());
    for r in records {
        let k = key(r);
        let p = match done.iter().find(|(s, _)| *s == k) {
            Some((_, p)) => p.clone(),
            None => {
                let p = profiles(r, nus)?;
                done.push((k, p.clone()));
                p
            }
        };
        out.push(p);
    }
    Some(out)
}

fn profiles_one_by_one(rec: &FieldRecord, nus: &[f64]) -> Option<Vec<Vec<f64>>> {
    nus.iter()
        .map(|&nu| {
            let mut spec = rec.spec.clone();
            spec.contact.material.poisson_ratio = nu;
            let d = 0.5 * spec.max_depth_mm;
            let mut m = ContactModel::build(spec).ok()?;
            let f = m.field(State {
                depth_mm: d,
                shear_n: 0.0,
                torque_nmm: 0.0,
            })?;
            Some(
                (0..R_SAMPLES)
                    .map(|i| {
                        let r = rec.a_mm * r_at(i);
                        f.grid.sample(&f.ux, r, 0.0) / d
                    })
                    .collect(),
            )
        })
        .collect()
}

/// The i-th radial sample, in punch radii.
fn r_at(i: usize) -> f64 {
    ANNULUS.0 + (ANNULUS.1 - ANNULUS.0) * i as f64 / (R_SAMPLES - 1) as f64
}

/// U(r; ν) per mm of depth from profiles at `nus`, linear in r; in ν linear between the
/// grid's neighbours, or the quadratic through three close ones (the refinement).
fn model_at(nus: &[f64], prof: &[Vec<f64>], a_mm: f64, r_mm: f64, nu: f64) -> f64 {
    let x = ((r_mm / a_mm - ANNULUS.0) / (ANNULUS.1 - ANNULUS.0) * (R_SAMPLES - 1) as f64)
        .clamp(0.0, (R_SAMPLES - 1) as f64);
    let i = (x.floor() as usize).min(R_SAMPLES - 2);
    let s = x - i as f64;
    let at = |p: &Vec<f64>| p[i] + s * (p[i + 1] - p[i]);
    if nus.len() == 3 {
        // Lagrange through the three.
        let (a, b, c) = (nus[0], nus[1], nus[2]);
        return at(&prof[0]) * (nu - b) * (nu - c) / ((a - b) * (a - c))
            + at(&prof[1]) * (nu - a) * (nu - c) / ((b - a) * (b - c))
            + at(&prof[2]) * (nu - a) * (nu - b) / ((c - a) * (c - b));
    }
    let j = nus.partition_point(|v| *v < nu).clamp(1, nus.len() - 1);
    let t = (nu - nus[j - 1]) / (nus[j] - nus[j - 1]);
    at(&prof[j - 1]) + t * (at(&prof[j]) - at(&prof[j - 1]))
}

/// The least of `chi2` on [lo, hi] by golden section.
fn golden(chi2: &dyn Fn(f64) -> f64, lo: f64, hi: f64) -> f64 {
    let (mut lo, mut hi) = (lo, hi);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    while hi - lo > NU_TOL {
        let (x1, x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        if chi2(x1) <= chi2(x2) {
            hi = x2;
        } else {
            lo = x1;
        }
    }
    0.5 * (lo + hi)
}

/// Half-width of the refinement about the grid's minimum, where the model's fields at three
/// ν are interpolated quadratically: the linear interpolation between grid nodes 0.015–0.05 apart
/// biases ν (the field is convex in ν; 0.00035 in this module's test); re-centred until the
/// minimum lies inside.
const REFINE: f64 = 0.003;

/// Why a fit that ends at the searched range's edge is no fit.
fn edge(nu: f64) -> String {
    let (lo, hi) = (NU_GRID[0], NU_GRID[NU_GRID.len() - 1]);
    format!(
        "the field fits best at ν {nu:.4}, at the edge of the range searched ({lo}–{hi}): the \
         gel's ν lies outside it, or the punch, the depths or the image scale are not what \
         the run says"
    )
}

/// Fits ν to the runs' fields; `Err` says why it cannot be told.
pub(super) fn fit_nu(records: &[FieldRecord]) -> Result<FieldNu, String> {
    let points: usize = records
        .iter()
        .flat_map(|r| r.steps.iter().map(|s| s.1.len()))
        .sum();
    if points < MIN_POINTS {
        return Err(format!(
            "the runs' frames show {points} marker readings between {} and {} punch radii, \
             fewer than {MIN_POINTS}",
            ANNULUS.0, ANNULUS.1
        ));
    }
    let no_field = "the mechanics has no field for a run's punch at some ν";
    let chi2_with = |nus: &[f64], profs: &[Vec<Vec<f64>>], nu: f64| -> f64 {
        let mut s = 0.0;
        for (rec, prof) in records.iter().zip(profs) {
            for (depth, pts) in &rec.steps {
                for &(r, ur) in pts {
                    s += (ur - depth * model_at(nus, prof, rec.a_mm, r, nu)).powi(2);
                }
            }
        }
        s
    };
    // The grid, interpolated: a fine scan over its range, then a golden-section search
    // about the scan's best.
    let profs = profiles_all(records, &NU_GRID).ok_or(no_field)?;
    let coarse = |nu: f64| chi2_with(&NU_GRID, &profs, nu);
    let (lo0, hi0) = (NU_GRID[0], NU_GRID[NU_GRID.len() - 1]);
    let step = (hi0 - lo0) / 400.0;
    let best = (0..=400)
        .map(|i| lo0 + step * i as f64)
        .min_by(|a, b| coarse(*a).total_cmp(&coarse(*b)))
        .ok_or("no ν to search")?;
    let nu = golden(&coarse, (best - step).max(lo0), (best + step).min(hi0));
    if nu >= hi0 - 1e-4 || nu <= lo0 + 1e-4 {
        return Err(edge(nu));
    }
    // Refined on the model's own fields at three ν about it, quadratic between; re-centred
    // while the minimum lies at the window's edge.
    let (mut c, mut fine, mut near, mut nu) = (nu, Vec::new(), [0.0; 3], nu);
    let mut inside = false;
    for _ in 0..4 {
        let centre = c.clamp(lo0 + REFINE, hi0 - REFINE);
        if !fine.is_empty() && centre == near[1] {
            break;
        }
        near = [centre - REFINE, centre, centre + REFINE];
        fine = profiles_all(records, &near).ok_or(no_field)?;
        nu = golden(&|x| chi2_with(&near, &fine, x), near[0], near[2]);
        if (nu - centre).abs() < 0.9 * REFINE {
            inside = true;
            break;
        }
        c = nu;
    }
    if !inside || nu >= hi0 - 1e-4 || nu <= lo0 + 1e-4 {
        return Err(edge(nu));
    }
    let chi2 = |x: f64| chi2_with(&near, &fine, x);
    let f0 = chi2(nu);
    let h = 1e-3_f64.min(0.5 * (nu - near[0])).min(0.5 * (near[2] - nu));
    let curvature = if h > 0.0 {
        (chi2(nu + h) - 2.0 * f0 + chi2(nu - h)) / (h * h)
    } else {
        0.0
    };
    let sigma2 = f0 / (points - 1) as f64;
    let sd = if curvature > 0.0 {
        (2.0 * sigma2 / curvature).sqrt().hypot(SD_FLOOR)
    } else {
        f64::INFINITY
    };
    if !sd.is_finite() {
        return Err("the field's misfit has no minimum in ν where it fits best".into());
    }
    let near_sides = records.iter().any(|r| {
        let layer = r.spec.contact.layer;
        let side = 0.5 * layer.width_mm.min(layer.length_mm);
        ANNULUS.1 * r.a_mm > side - 2.0 * layer.thickness_mm
    });
    Ok(FieldNu {
        nu,
        sd,
        runs: records.len(),
        points,
        rms_um: (f0 / points as f64).sqrt() * 1e3,
        near_sides,
        annulus: ANNULUS,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mechanics::contact::Contact;
    use mechanics::geometry::presets;
    use mechanics::response::Quality;

    fn box_punch(nu: f64) -> ModelSpec {
        let mut material = presets::box_material();
        material.poisson_ratio = nu;
        material.youngs_modulus_mpa = 1.0;
        ModelSpec {
            contact: Contact {
                layer: presets::BOX_LAYER,
                material,
                indenter: mechanics::Indenter::FlatCircle { diameter_mm: 9.5 },
            },
            max_depth_mm: 0.84,
            shear: false,
            twist: false,
            field_view_mm: Some((45.36, 40.32)),
            pressing_friction: false,
            quality: Quality::default(),
        }
    }

    /// Markers at scattered radii in the annulus, seeing the model's own field of a gel of
    /// ν 0.4763 (between the grid's nodes) at three depths, with ±0.5 µm of noise: the fit
    /// finds ν within 0.0002 where the coarse grid alone is 0.00035 off, and says it is
    /// well told; a record of fewer readings than it needs is refused.
    #[test]
    fn the_field_around_a_punch_tells_nu() {
        let truth = 0.4763;
        let spec = box_punch(0.49);
        let a = 4.75;
        let rec = FieldRecord {
            a_mm: a,
            steps: Vec::new(),
            spec: spec.clone(),
        };
        let prof = profiles(&rec, &[truth]).expect("field")[0].clone();
        let mut noise = 0.37_f64;
        let steps: Vec<(f64, Vec<(f64, f64)>)> = [0.2, 0.5, 0.8]
            .iter()
            .map(|&d| {
                let pts = (0..40)
                    .map(|k| {
                        let r = a * (ANNULUS.0 + (ANNULUS.1 - ANNULUS.0) * (k as f64 + 0.5) / 40.0);
                        noise = (noise * 997.0 + 0.123).fract();
                        let u =
                            d * model_at(&[truth, 1.0], &[prof.clone(), prof.clone()], a, r, truth);
                        (r, u + (noise - 0.5) * 1e-3)
                    })
                    .collect();
                (d, pts)
            })
            .collect();
        let rec = FieldRecord {
            a_mm: a,
            steps,
            spec,
        };
        let fit = fit_nu(std::slice::from_ref(&rec)).expect("fitted");
        assert!((fit.nu - truth).abs() < 2e-4, "{fit:?}");
        assert!(fit.sd >= SD_FLOOR && fit.sd < 1.5 * SD_FLOOR, "{fit:?}");
        assert_eq!(fit.points, 120);
        let few = FieldRecord {
            a_mm: a,
            steps: vec![(0.5, rec.steps[1].1[..5].to_vec())],
            spec: rec.spec.clone(),
        };
        let why = fit_nu(&[few]).expect_err("too few readings");
        assert!(why.contains("fewer than"), "{why}");
        // A field half again as large as any ν's in the range: refused at the range's edge.
        let big = FieldRecord {
            a_mm: a,
            steps: rec
                .steps
                .iter()
                .map(|(d, p)| (*d, p.iter().map(|&(r, u)| (r, 1.6 * u)).collect()))
                .collect(),
            spec: rec.spec.clone(),
        };
        let why = fit_nu(&[big]).expect_err("no ν makes it");
        assert!(why.contains("edge of the range"), "{why}");
    }

    /// The radial component about a centre, in mm, whichever way the image's axes run.
    #[test]
    fn a_markers_radial_displacement_is_taken_about_the_centre() {
        let c = [100.0, 50.0];
        let (r, u) = radial([103.0, 54.0], [0.3, 0.4], c, 0.1).expect("off the centre");
        assert!(
            (r - 0.5).abs() < 1e-12 && (u - 0.05).abs() < 1e-12,
            "{r} {u}"
        );
        // Mirrored in y (an image's rows run down): the same radius and radial motion.
        let (r2, u2) = radial([103.0, 46.0], [0.3, -0.4], c, 0.1).expect("mirrored");
        assert!((r2 - r).abs() < 1e-12 && (u2 - u).abs() < 1e-12);
        // Tangential motion has no radial part; the centre itself has no radius.
        let (_, ut) = radial([103.0, 54.0], [-0.4, 0.3], c, 0.1).expect("tangential");
        assert!(ut.abs() < 1e-12);
        assert!(radial(c, [1.0, 0.0], c, 0.1).is_none());
        assert!(radial([1.0, 1.0], [f64::NAN, 0.0], c, 0.1).is_none());
    }
}
