//! The tangential (shear or twist) backbone of one contact state: force against stage
//! displacement from full stick to full slip, with the stick fraction and tractions at
//! each level.

use std::f64::consts::PI;

use super::{ContactModel, Kind, TangentialTable, tol};
use crate::friction::Backbone;
use crate::operator::Compliance;
use crate::solve::{Tangential, TangentialSolution, tangential};

impl ContactModel {
    /// Solves the tangential backbone at `depth_mm` (unit depth for flat punches).
    pub(super) fn tangential_table(&mut self, depth_mm: f64, kind: Kind) -> TangentialTable {
        let c = &self.spec.contact;
        let mu = c.material.friction;
        let op = self.op_for(depth_mm);
        let grid = op.grid();
        // Pressing: the punch does not move sideways, so contact points stick where they
        // touched while the coupling pushes the surface outward (on a pressure found with
        // friction, this is the coupled solution's own traction). A curved indenter pressed
        // with friction starts from its loading path's state instead.
        let (p, press, (sx, sy)) = if self.curved_friction() {
            let h = c.layer.thickness_mm;
            let s = self.pressed(super::quantise(depth_mm, h));
            debug_assert_eq!(s.grid, grid, "a pressed state on another depth's grid");
            let (mut sx, mut sy) = (vec![0.0; grid.len()], vec![0.0; grid.len()]);
            op.tangential_from_normal(&s.p, &mut sx, &mut sy);
            let a = grid.area();
            let press = TangentialSolution {
                fx_n: s.qx.iter().sum::<f64>() * a,
                fy_n: s.qy.iter().sum::<f64>() * a,
                stick: s.stick,
                qx: s.qx,
                qy: s.qy,
                outer: 0,
                converged: true,
            };
            (s.p, press, (sx, sy))
        } else {
            let p = self.pressure_on(&op, depth_mm);
            let (press, s) = super::flat::held_by_friction(&op, &p, mu);
            (p, press, s)
        };
        let (mut u0x, mut u0y) = (vec![0.0; grid.len()], vec![0.0; grid.len()]);
        op.tangential(&press.qx, &press.qy, &mut u0x, &mut u0y);
        for i in 0..grid.len() {
            u0x[i] += sx[i];
            u0y[i] += sy[i];
        }
        let total_p: f64 = p.iter().sum::<f64>() * grid.area();
        let a_eff = (p.iter().filter(|v| **v > 0.0).count() as f64 * grid.area() / PI).sqrt();
        // The linear (full-stick) stiffness sets the scale of the levels.
        let unit = 1e-3;
        let solve = |x: f64, init: Option<&(Vec<f64>, Vec<f64>)>| {
            let (tx, ty): (Vec<f64>, Vec<f64>) = (0..grid.len())
                .map(|i| {
                    let (gx, gy) = grid.xy(i);
                    match kind {
                        Kind::Shear => (u0x[i] + x, u0y[i]),
                        Kind::Twist => (u0x[i] - x * gy, u0y[i] + x * gx),
                    }
                })
                .unzip();
            tangential(&Tangential {
                op: &op,
                p: &p,
                mu,
                target: (&tx, &ty),
                source: Some((&sx, &sy)),
                x_only: false,
                initial: init.map(|(a, b)| (a.as_slice(), b.as_slice())),
                tol: tol(),
            })
        };
        let measure = |s: &crate::solve::TangentialSolution| -> f64 {
            match kind {
                Kind::Shear => s.fx_n - press.fx_n,
                Kind::Twist => s.torque_nmm(grid) - press.torque_nmm(grid),
            }
        };
        let probe = solve(
            unit * if kind == Kind::Twist {
                1.0 / a_eff.max(1e-6)
            } else {
                1.0
            },
            None,
        );
        let x_probe = unit
            * if kind == Kind::Twist {
                1.0 / a_eff.max(1e-6)
            } else {
                1.0
            };
        let stiffness = measure(&probe) / x_probe;
        let limit = match kind {
            Kind::Shear => mu * total_p,
            Kind::Twist => {
                mu * (0..grid.len())
                    .map(|i| p[i] * grid.xy(i).0.hypot(grid.xy(i).1))
                    .sum::<f64>()
                    * grid.area()
            }
        };
        let x_lin = if stiffness > 0.0 {
            limit / stiffness
        } else {
            0.0
        };
        let mut xs = vec![0.0];
        let mut fs = vec![0.0];
        let mut stick = vec![1.0];
        let mut tractions = vec![(press.qx.clone(), press.qy.clone())];
        let mut prev: Option<(Vec<f64>, Vec<f64>)> = None;
        // Under torsion the centre's slip βr vanishes, so a few central cells stick until
        // large twists: levels go further, and under 2 % stick counts as full slip.
        for frac in [
            0.1, 0.3, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.35, 1.5, 1.7, 2.0, 2.5, 3.0, 4.0,
            6.0,
        ] {
            let x = frac * x_lin;
            let s = solve(x, prev.as_ref());
            let f = measure(&s).min(limit);
            let sf = s.stick_fraction(&p);
            xs.push(x);
            // A backbone must not decrease (rounding near full slip).
            fs.push(f.max(*fs.last().unwrap_or(&0.0)));
            stick.push(sf);
            tractions.push((s.qx.clone(), s.qy.clone()));
            prev = Some((s.qx, s.qy));
            if sf < 0.02 {
                break;
            }
        }
        // The last point is full slip: the backbone saturates there.
        if let Some(last) = fs.last_mut() {
            *last = limit.max(*last);
        }
        // The levels come from this grid's pressure, whose total is not the model's Fz (a
        // flat punch's force has exact κ or is extrapolated across grids; a curved one's is
        // solved on a grid adapted to each depth, and this grid has only `cells_curved`
        // cells across the contact's √(A/π)): scaled as the normal force is, so the slip
        // limit is μ times the model's Fz. Unscaled it was 0.579 Fz for μ = 0.6 on the box's
        // 9.5 mm punch and 0.94 μ·Fz on the lifting can at 0.3 mm.
        // The levels' tractions over the pressed state's are scaled with them, so the
        // tractions a field is given for a force carry that force.
        if total_p > 0.0 {
            let calibration = self.normal_force_n(depth_mm) / total_p;
            fs.iter_mut().for_each(|f| *f *= calibration);
            for (qx, qy) in tractions.iter_mut().skip(1) {
                for (q, q0) in qx.iter_mut().zip(&press.qx) {
                    *q = q0 + calibration * (*q - q0);
                }
                for (q, q0) in qy.iter_mut().zip(&press.qy) {
                    *q = q0 + calibration * (*q - q0);
                }
            }
        }
        if let Some(last) = stick.last_mut() {
            *last = 0.0;
        }
        TangentialTable {
            backbone: Backbone { x: xs, f: fs },
            stick_fraction: stick,
            tractions,
            pressing: (press.qx, press.qy),
            grid,
        }
    }
}
