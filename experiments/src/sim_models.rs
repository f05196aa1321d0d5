//! What a simulated bench will solve for a protocol, and what it leaves out (`gelrig plan`).
//!
//! The plant builds only what the opened devices ask for (`simbench`'s `PlantNeeds`): the
//! normal table always, the shear and twist backbones for a shear stage, a rotation tripod
//! or a grasp, the surface fields for a camera. The plan says which, at which fidelity, and
//! what that fidelity was measured to cost in error and time on the shipped protocols.

use rig::config::{AxisRole, Fidelity, RigConfig};
use serde::Serialize;

use crate::protocol::compile::Compiled;
use crate::protocol::plant_spec;
use crate::protocol::schema::Protocol;

/// The contact models a simulated run solves, and those it leaves out.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimModels {
    /// The fidelity level (`sim: {fidelity}`, `--fidelity`).
    pub fidelity: Fidelity,
    /// The level's resolution, in words.
    pub resolution: String,
    /// Models solved: (name, what).
    pub solved: Vec<(String, String)>,
    /// Models left out: (name, why).
    pub left_out: Vec<(String, String)>,
    /// What the level was measured to cost and miss on the shipped protocols.
    pub expected: String,
}

/// Measured by `cargo run --release -p gelrig --example fidelity_study` (docs/benchmarks/
/// simulator.md, "Fidelity levels"): the worst step force's distance from the reference
/// level over the shipped protocols, % of the run's range, and the level's cold run time
/// against the default's (median over the shipped protocols).
pub fn expected(level: Fidelity) -> &'static str {
    match level {
        Fidelity::Fast => FAST_EXPECTED,
        Fidelity::Default => DEFAULT_EXPECTED,
        Fidelity::Reference => REFERENCE_EXPECTED,
    }
}

const FAST_EXPECTED: &str = "step forces within 0.6 % of the reference level's range on the \
shipped indentation protocols' flat punches, 3.7 % on curved indenters; grasps, whose slips and \
regrips are events: lifting and slipping within 8 % at the worst step, but regrips 25–27 % \
(their trials regrip differently: study regrips at default); cold runs 1.4–7.4× quicker than \
default (median 1.9×)";
const DEFAULT_EXPECTED: &str = "step forces within 0.6 % of the reference level's range on the \
shipped indentation protocols; grasps, whose slips and regrips are events, 2–12 % at the worst \
step over seeds (0.8–5.3 % root-mean-square): judge them over seeds";
const REFERENCE_EXPECTED: &str = "the level the others are measured against; cold runs 2.3–9.3× \
the default's time, warm up to 2.2× (its 512² field)";

/// The simulated bench's models for `protocol` on `rig`, or `None` on a rig without one.
pub fn sim_models(protocol: &Protocol, compiled: &Compiled, rig: &RigConfig) -> Option<SimModels> {
    if !rig.uses_sim() {
        return None;
    }
    let spec = plant_spec(protocol, compiled).ok()?;
    let level = rig.fidelity();
    let q = simbench::quality_for(level);
    let c = &spec.contact;
    let needs = &compiled.needs;
    let grasp = spec.object_mass_g.is_some();
    let flat = c.indenter.is_flat();
    let pressing = if rig.presses_with_friction() {
        "pressed with friction"
    } else {
        "frictionless pressure"
    };
    let mut solved = vec![(
        "normal".to_string(),
        if flat {
            format!("flat punch, {} cells across it, {pressing}", q.cells_flat)
        } else {
            format!(
                "curved indenter, tables to {:.2} mm deep, {} cells across 1.2 contact diameters, \
                 {pressing}{}",
                spec.max_depth_mm,
                q.cells_curved,
                if rig.presses_with_friction() {
                    format!(" along a {}-increment loading path", q.path_steps)
                } else {
                    String::new()
                }
            )
        },
    )];
    let mut left_out = Vec::new();
    let mut channel = |name: &str, used: bool, why_used: &str, why_not: &str| {
        if used {
            solved.push((name.to_string(), why_used.to_string()));
        } else {
            left_out.push((name.to_string(), why_not.to_string()));
        }
    };
    channel(
        "shear",
        needs.axes.contains(&AxisRole::Shear) || grasp,
        if grasp {
            "partial-slip backbone (the grasp loads the gel along the lift)"
        } else {
            "partial-slip backbone (a shear stage moves)"
        },
        "no shear stage and no grasp",
    );
    channel(
        "twist",
        needs.axes.contains(&AxisRole::Rotation) || grasp,
        if grasp {
            "torsional backbone (the grasp twists the gel about its normal)"
        } else {
            "torsional backbone (the rotation tripod turns)"
        },
        "no rotation stage and no grasp",
    );
    let field = format!(
        "{0}×{0} grid over the {1:.1} × {2:.1} mm view (the camera's frames)",
        q.field_cells, spec.view_width_mm, spec.view_height_mm
    );
    channel("fields", needs.camera, &field, "no camera records frames");
    Some(SimModels {
        fidelity: level,
        resolution: format!(
            "{} cells across a flat punch, {} across a curved contact, {}² field grid, \
             {}-increment loading path{}",
            q.cells_flat,
            q.cells_curved,
            q.field_cells,
            q.path_steps,
            if q.extrapolate_flat {
                ", non-circular punches extrapolated across two grids"
            } else {
                ""
            }
        ),
        solved,
        left_out,
        expected: expected(level).to_string(),
    })
}

impl SimModels {
    /// One line for the start of a run: the level, what is solved, what is left out and why.
    pub fn summary(&self) -> String {
        let solved: Vec<&str> = self.solved.iter().map(|(n, _)| n.as_str()).collect();
        let mut line = format!(
            "simulated bench at fidelity {}: solves {}",
            self.fidelity.as_str(),
            solved.join(", ")
        );
        if !self.left_out.is_empty() {
            let out: Vec<String> = self
                .left_out
                .iter()
                .map(|(n, why)| format!("{n} ({why})"))
                .collect();
            line.push_str(&format!("; leaves out {}", out.join(", ")));
        }
        line
    }

    /// The section `gelrig plan` prints.
    pub fn render(&self) -> String {
        let mut o = format!(
            "simulated bench, fidelity {} ({})\n",
            self.fidelity.as_str(),
            self.resolution
        );
        for (name, what) in &self.solved {
            o.push_str(&format!("  solves     {name:<7} {what}\n"));
        }
        for (name, why) in &self.left_out {
            o.push_str(&format!("  leaves out {name:<7} {why}\n"));
        }
        o.push_str(&format!("  expected   {}\n", self.expected));
        o
    }
}
