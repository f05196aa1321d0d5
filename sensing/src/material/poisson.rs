//! Poisson's ratio from pressing runs of two indenters or more on one gel.
//!
//! One indenter's force is E·φ(d; ν): for a flat punch on the bonded layer
//! 2a·E·κ(a/h, ν)·d/(1 − ν²), so its record fits E for whatever ν is assumed — a force
//! record cannot tell them apart. Indenters of different a/h do not share φ's dependence on
//! ν: κ rises faster with ν the wider the punch is against the layer (the box's 9.5 and
//! 12.68 mm punches' force ratio moves 1.4–1.9 % per 0.01 of ν; BENCHMARKS.md, "Poisson's
//! ratio from two punch sizes"). So each run is fitted on its own at the protocols' ν₀, giving its
//! apparent modulus sₖ, and ν is where the runs' moduli agree: sₖ/cₖ(ν) the same for every
//! run, with cₖ(ν) the least-squares ratio of the run's force law at ν to its law at ν₀ over
//! the depths it reached — exact for a flat punch, whose law only scales with ν; for a
//! sphere the law's shape moves a little too, and the ratio is its best single scale.
//!
//! The spread is weighed by each modulus's Gauss–Newton uncertainty, and ν's uncertainty is
//! where that weighted spread has risen by one (Δχ² = 1; with three runs or more, scaled by
//! the spread left at the minimum over its degrees of freedom where that exceeds one): a
//! lower bound, as the moduli's are, and one that holds only as far as the force laws are
//! the bench's — an error of 1 % in the two punches' relative force moves ν by about 0.006.

use analysis::material_fit::{PressRecord, fit_material};

use super::law::{interp, law_scale};

/// Poisson's ratio where the runs' moduli agree.
#[derive(Debug, Clone, PartialEq)]
pub struct PoissonFit {
    /// ν.
    pub nu: f64,
    /// Its standard uncertainty (a lower bound: see the module).
    pub sd: f64,
    /// The ν the protocols assumed (where the search started).
    pub assumed: f64,
    /// How many punch sizes' runs told it.
    pub indenters: usize,
    /// d ln E∞/dν at ν: how far ν's uncertainty moves the modulus.
    pub log_modulus_per_nu: f64,
}

/// The range searched: below 0.3 no gel of a GelSight lies, and at 0.5 the bonded layer's
/// force law has no finite limit for the thin pads.
const NU_RANGE: (f64, f64) = (0.30, 0.4995);

/// Coarse grid over [`NU_RANGE`], denser where gels lie (κ changes fastest near ½).
const NU_GRID: [f64; 12] = [
    0.30, 0.35, 0.40, 0.43, 0.45, 0.46, 0.47, 0.48, 0.485, 0.49, 0.495, 0.4995,
];

/// ν found to this, then ends the search (its effect on κ is a few 10⁻⁴ of the force).
const NU_TOL: f64 = 2e-5;

/// Largest ν uncertainty that still tells anything: the runs' indenters must differ enough
/// in a/h for their moduli to part with ν.
const MAX_SD: f64 = 0.02;

/// Fits ν to `records` whose force laws at ν₀ are `tables0` and at any ν `table_at(k, ν)`;
/// `indenters` how many different indenters they press with. `Err` says why ν cannot be
/// told (then it stays ν₀).
pub(super) fn fit_poisson(
    records: &[PressRecord],
    tables0: &[(Vec<f64>, Vec<f64>)],
    nu0: f64,
    indenters: usize,
    table_at: &dyn Fn(usize, f64) -> Option<(Vec<f64>, Vec<f64>)>,
) -> Result<PoissonFit, String> {
    // Each run's apparent modulus at ν₀, and the depths it reached past its contact.
    let mut moduli = Vec::new();
    for (k, r) in records.iter().enumerate() {
        let fit = fit_material(std::slice::from_ref(r), &|_, d| interp(&tables0[k], d))
            .ok_or_else(|| {
                "one of the pressing runs cannot be fitted on its own, so its modulus cannot \
                 be set against the others'"
                    .to_string()
            })?;
        let s = fit.modulus_ratio;
        let d0 = fit.offsets_mm.first().map_or(0.0, |o| o.value);
        let deepest = r.depth_knots.iter().map(|k| k.1).fold(0.0, f64::max) - d0;
        if !(s.value > 0.0 && deepest > 0.0) {
            return Err("a pressing run's own fit gives no positive modulus".into());
        }
        moduli.push((s.value, s.sd.max(1e-6 * s.value), deepest));
    }
    // cₖ(ν): the least-squares scale from the law at ν₀ to the law at ν over (0, deepest].
    let ratio = |k: usize, nu: f64| -> Option<f64> {
        law_scale(&tables0[k], &table_at(k, nu)?, moduli[k].2)
    };
    // The weighted spread of ln(sₖ/cₖ(ν)) about its weighted mean.
    let chi2 = |nu: f64| -> Option<f64> {
        let mut ys = Vec::with_capacity(moduli.len());
        for (k, (s, sd, _)) in moduli.iter().enumerate() {
            ys.push(((s / ratio(k, nu)?).ln(), (s / sd).powi(2)));
        }
        let w: f64 = ys.iter().map(|y| y.1).sum();
        let mean = ys.iter().map(|(y, wk)| y * wk).sum::<f64>() / w;
        Some(ys.iter().map(|(y, wk)| wk * (y - mean).powi(2)).sum())
    };
    let no_law = || "the mechanics has no force law for a run's indenter at some ν".to_string();
    let grid: Vec<f64> = NU_GRID
        .iter()
        .map(|&nu| chi2(nu).ok_or_else(no_law))
        .collect::<Result<_, _>>()?;
    let i = (0..grid.len())
        .min_by(|&a, &b| grid[a].total_cmp(&grid[b]))
        .ok_or_else(no_law)?;
    // Golden-section search in the bracket about the grid's best.
    let (mut lo, mut hi) = (
        NU_GRID[i.saturating_sub(1)],
        NU_GRID[(i + 1).min(NU_GRID.len() - 1)],
    );
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (chi2(x1).ok_or_else(no_law)?, chi2(x2).ok_or_else(no_law)?);
    while hi - lo > NU_TOL {
        if f1 <= f2 {
            (hi, x2, f2) = (x2, x1, f1);
            x1 = hi - g * (hi - lo);
            f1 = chi2(x1).ok_or_else(no_law)?;
        } else {
            (lo, x1, f1) = (x1, x2, f2);
            x2 = lo + g * (hi - lo);
            f2 = chi2(x2).ok_or_else(no_law)?;
        }
    }
    let nu = 0.5 * (lo + hi);
    if nu >= NU_RANGE.1 - NU_TOL {
        return Err(format!(
            "the runs' moduli agree only at ν {} or above, where the layer's force law is \
             too steep in ν to tell it: a gel that near incompressible",
            NU_RANGE.1
        ));
    }
    if nu <= NU_RANGE.0 + NU_TOL {
        return Err(format!(
            "the runs' moduli agree nowhere inside ν {}–{} (closest at {nu:.4}): their \
             indenters or contact offsets are not what their protocols say",
            NU_RANGE.0, NU_RANGE.1
        ));
    }
    // Δχ² = 1 from the curvature about the minimum.
    let h = 1e-3_f64.min(0.5 * (NU_RANGE.1 - nu));
    let (fm, f0, fp) = (
        chi2(nu - h).ok_or_else(no_law)?,
        chi2(nu).ok_or_else(no_law)?,
        chi2(nu + h).ok_or_else(no_law)?,
    );
    let curvature = (fp - 2.0 * f0 + fm) / (h * h);
    // With more runs than the two a ν and a modulus can always reconcile, a spread left at
    // the minimum beyond the moduli's own uncertainty widens ν's.
    let dof = moduli.len().saturating_sub(2);
    let scale = if dof > 0 {
        (f0 / dof as f64).max(1.0).sqrt()
    } else {
        1.0
    };
    let sd = if curvature > 0.0 {
        scale * (2.0 / curvature).sqrt()
    } else {
        f64::INFINITY
    };
    // ln E∞(ν): the moduli's weighted mean of ln(sₖ/cₖ(ν)).
    let log_modulus = |nu: f64| -> Option<f64> {
        let (mut num, mut den) = (0.0, 0.0);
        for (k, (s, sd, _)) in moduli.iter().enumerate() {
            let w = (s / sd).powi(2);
            num += w * (s / ratio(k, nu)?).ln();
            den += w;
        }
        Some(num / den)
    };
    let log_modulus_per_nu = (log_modulus(nu + h).ok_or_else(no_law)?
        - log_modulus(nu - h).ok_or_else(no_law)?)
        / (2.0 * h);
    if sd.is_nan() || sd > MAX_SD {
        return Err(format!(
            "the runs' indenters part too little with ν to tell it (±{sd:.3}); pressing runs \
             of two punch sizes far apart against the layer's thickness can"
        ));
    }
    Ok(PoissonFit {
        nu,
        sd,
        assumed: nu0,
        indenters,
        log_modulus_per_nu,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two flat punches on one layer, pressed in held steps: their laws at ν are the layer's
    /// κ(a/h, ν) over (1 − ν²). The records are made at ν = 0.47 and read as if the
    /// protocols said 0.49.
    #[test]
    fn two_punch_sizes_tell_nu_and_one_does_not() {
        let h = 4.2;
        let law = |a: f64, nu: f64| -> (Vec<f64>, Vec<f64>) {
            let k = 2.0 * a * mechanics::contact::layer_stiffening(a / h, nu) / (1.0 - nu * nu);
            let d: Vec<f64> = (0..=100).map(|i| 1.0 * i as f64 / 100.0).collect();
            let f = d.iter().map(|x| k * x).collect();
            (d, f)
        };
        // A gel of one Prony term (0.3, 5 s), pressed in five 0.08 mm steps of 0.5 s ramps
        // held 30 s, its force the hereditary integral of the elastic force (each ramp
        // taken as a step at its end: both punches alike).
        let record = |a: f64, e_mpa: f64, nu: f64| -> PressRecord {
            let table = law(a, nu);
            let (w, tau) = (0.3, 5.0);
            let mut knots = Vec::new();
            let mut jumps: Vec<(f64, f64)> = Vec::new();
            let (mut t_s, mut f_n) = (Vec::new(), Vec::new());
            for step in 1..=5 {
                let t0 = (step - 1) as f64 * 30.5;
                let depth = 0.08 * step as f64;
                knots.push((t0, depth - 0.08));
                knots.push((t0 + 0.5, depth));
                jumps.push((
                    t0 + 0.5,
                    interp(&table, depth) - interp(&table, depth - 0.08),
                ));
                for i in 1..=600 {
                    let t = t0 + 0.5 + i as f64 * 0.05;
                    let memory: f64 = jumps
                        .iter()
                        .map(|(tj, df)| w * df * (-(t - tj) / tau).exp())
                        .sum();
                    t_s.push(t);
                    f_n.push(e_mpa * (interp(&table, depth) + memory));
                }
            }
            PressRecord {
                t_s,
                f_n,
                depth_knots: knots,
            }
        };
        let (a1, a2, e) = (4.75, 6.34, 0.25);
        let records = [record(a1, e, 0.47), record(a2, e, 0.47)];
        let tables0 = [law(a1, 0.49), law(a2, 0.49)];
        let sizes = [a1, a2];
        let p = fit_poisson(&records, &tables0, 0.49, 2, &|k, nu| {
            Some(law(sizes[k], nu))
        })
        .expect("two sizes tell ν");
        assert!((p.nu - 0.47).abs() < 2e-3, "{p:?}");
        assert!(p.sd > 0.0 && p.sd < MAX_SD, "{p:?}");
        // A lower ν softens κ, so the same forces mean a stiffer gel: E∞ falls as ν rises.
        assert!(p.log_modulus_per_nu < 0.0, "{p:?}");
        // Two runs of one punch agree at every ν: nothing to tell.
        let same = [record(a1, e, 0.47), record(a1, 1.1 * e, 0.47)];
        let tables = [law(a1, 0.49), law(a1, 0.49)];
        let err = fit_poisson(&same, &tables, 0.49, 1, &|_, nu| Some(law(a1, nu)))
            .expect_err("one size cannot tell ν");
        assert!(
            err.contains("part too little") || err.contains("agree nowhere"),
            "{err}"
        );
    }
}
