//! Where a fitted gel's Poisson's ratio comes from: the marker field around a flat circular
//! punch (from one run with frames), or the forces of two flat punch sizes, or neither — and
//! then why ν was held at the protocols' value. Part of [`super::fit`].

use analysis::material_fit::PressRecord;

use super::field_nu::FieldRecord;
use super::law::ForceLaw;
use super::run::{FittedNu, PRESSING_AXES, Run};

/// Flat punches whose a/h differ by less than this factor count as one size for ν: their
/// force ratio moves too little with ν for the model's own error to stay out of it.
const SIZES_APART: f64 = 1.15;

/// How many sizes the flat punches come in: sizes closer than [`SIZES_APART`] in a/h part
/// too little with ν to count as two.
pub(super) fn distinct_sizes(flat: &[(usize, f64)]) -> usize {
    let mut a: Vec<f64> = flat.iter().map(|f| f.1).collect();
    a.sort_by(f64::total_cmp);
    let mut n = usize::from(!a.is_empty());
    let mut last = a.first().copied().unwrap_or(0.0);
    for &x in &a {
        if x > last * SIZES_APART {
            n += 1;
            last = x;
        }
    }
    n
}

/// ν from the marker fields around the flat circular punches (`flat`: indices into
/// `pressing`), each run at the contact offset its record was fitted with at ν₀ (a flat
/// punch's hardly moves with ν); with the reasons of runs whose frames gave no field. Runs
/// without frames give none.
#[allow(clippy::type_complexity)]
pub(super) fn nu_from_fields(
    read: &[Run],
    pressing: &[(usize, PressRecord)],
    flat: &[(usize, f64)],
    laws: &[&ForceLaw],
    offsets_mm: &[f64],
) -> (
    Option<Result<super::field_nu::FieldNu, String>>,
    Vec<String>,
) {
    let mut notes: Vec<String> = Vec::new();
    let mut recs: Vec<FieldRecord> = Vec::new();
    for &(j, _) in flat {
        let run = &read[pressing[j].0];
        if run.data.frames.len() < 2 {
            continue;
        }
        let rec = crate::run_data::read_run(&run.dir)
            .map_err(|e| format!("its frames do not track ({e})"))
            .and_then(|data| {
                super::field_nu::field_record(
                    &data,
                    &laws[j].spec,
                    run.view_mm,
                    PRESSING_AXES[0],
                    offsets_mm[j],
                )
            });
        match rec {
            Ok(r) => recs.push(r),
            Err(why) => notes.push(format!("{}: {why}", run.dir.display())),
        }
    }
    let field = match (recs.is_empty(), notes.is_empty()) {
        (false, _) => Some(super::field_nu::fit_nu(&recs)),
        (true, false) => Some(Err(notes.join("; "))),
        (true, true) => None,
    };
    (field, notes)
}

/// The ν to fit the record at: the marker field's where it told one, else the two punch
/// sizes' forces', with how it was told.
pub(super) fn chosen_nu(
    field: &Option<Result<super::field_nu::FieldNu, String>>,
    poisson: &Option<Result<super::poisson::PoissonFit, String>>,
    laws: &[&ForceLaw],
) -> Option<FittedNu> {
    let pressing_model = if laws.iter().any(|l| l.spec.pressing_friction) {
        "the punch face stuck (pressed with friction: the rig file's `contact:` or `sim:` \
         `pressing_friction`, default true)"
    } else {
        "a frictionless punch face (the rig file's `pressing_friction: false`)"
    };
    match (field, poisson) {
        (Some(Ok(f)), _) => Some(FittedNu {
            nu: f.nu,
            sd: f.sd,
            per_nu: None,
            how: format!(
                "from the marker field around {} flat punch run(s) ({} marker readings from \
                 {} to {} punch radii, rms misfit {:.2} µm; the field independent of the \
                 modulus, of the contact model with {pressing_model}; the ± the markers' noise \
                 and {} of the fit's own in quadrature{})",
                f.runs,
                f.points,
                f.annulus.0,
                f.annulus.1,
                f.rms_um,
                super::field_nu::SD_FLOOR,
                if f.near_sides {
                    "; the markers used reach within two layer thicknesses of the pad's \
                     sides, where a real pad's field departs from the infinite layer's"
                } else {
                    ""
                }
            ),
        }),
        (_, Some(Ok(p))) => Some(FittedNu {
            nu: p.nu,
            sd: p.sd,
            per_nu: Some(p.log_modulus_per_nu),
            how: format!(
                "where the apparent moduli of {} flat punches' pressing runs agree (each run \
                 fitted on its own)",
                p.indenters
            ),
        }),
        _ => None,
    }
}

/// The method not taken, where it told ν or was tried: the fitted ν's check.
pub(super) fn nu_checks(
    chosen: &Option<FittedNu>,
    field: &Option<Result<super::field_nu::FieldNu, String>>,
    poisson: &Option<Result<super::poisson::PoissonFit, String>>,
    field_notes: &[String],
) -> Vec<String> {
    let mut checks = Vec::new();
    if let (Some(_), Some(Ok(_)), Some(Ok(p))) = (chosen, field, poisson) {
        checks.push(format!(
            "poisson_ratio check: the two punch sizes' forces agree at {:.4} ± {:.4}",
            p.nu, p.sd
        ));
    }
    if let (Some(_), Some(Err(why))) = (chosen, field) {
        checks.push(format!(
            "poisson_ratio check: the marker field did not tell ν: {why}"
        ));
    } else if let (Some(Ok(_)), false) = (field, field_notes.is_empty()) {
        checks.push(format!(
            "poisson_ratio check: runs whose frames gave no field: {}",
            field_notes.join("; ")
        ));
    }
    checks
}

/// Why ν was held at the protocols' value (read where none was fitted).
pub(super) fn held_reason(
    read: &[Run],
    pressing: &[(usize, PressRecord)],
    field: &Option<Result<super::field_nu::FieldNu, String>>,
    poisson: &Option<Result<super::poisson::PoissonFit, String>>,
    refit_failed: Option<String>,
) -> String {
    let kinds = {
        let mut all: Vec<&str> = pressing
            .iter()
            .map(|(k, _)| read[*k].indenter.as_str())
            .collect();
        all.sort_unstable();
        all.dedup();
        all.len()
    };
    let field_why = match field {
        Some(Err(why)) => format!("; the field: {why}"),
        _ => String::new(),
    };
    match poisson {
        _ if refit_failed.is_some() => refit_failed.unwrap_or_default(),
        Some(Err(why)) => format!("{why}{field_why}"),
        _ if kinds >= 2 => format!(
            "only flat circular punches tell ν: by their field around them where frames \
             were recorded, or by the forces of two sizes (a/h 15 % apart or more); a curved \
             indenter's force law changes its shape with ν and its contact offset trades with \
             the modulus{field_why}"
        ),
        _ => format!(
            "a force record of one indenter cannot tell E from ν; the marker field around a \
             flat circular punch can, and so can pressing runs of two flat punch sizes{field_why}"
        ),
    }
}
