//! Stick, incipient slip and slip of a shear or torsion block, per step, from three
//! independent cues (thesis §4.4, §5.2, §6.2):
//!
//! - (a) **force**: the tangential force (or torque) leaves the slope of the first steps
//!   (incipient), then stops rising or drops (slip) — Fig. 4-10, 4-16, 6-15;
//! - (b) **central line**: in stick the whole contact moves with the indenter, so the
//!   central-line displacement at the contact centre equals that near the contact edge;
//!   slip starts at the edge, so the centre pulls ahead — Fig. 4-13, 5-7 (for torsion: the
//!   inner markers rotate more than the outer ones in the contact, Fig. 6-16);
//! - (c) **contact centre against the indenter**: the gel under the contact centre
//!   follows the indenter while anything sticks, then lags and stops — Fig. 5-5, 6-12, 6-17.
//!
//! The cues are independent measurements; the report says which agreed.

/// State of the contact at the end of a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum State {
    /// The contact moves with the indenter.
    Stick,
    /// Part of the contact slides (from its edge).
    Incipient,
    /// The whole contact slides.
    Slip,
}

impl State {
    /// Lower-case name for tables and JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Stick => "stick",
            Self::Incipient => "incipient",
            Self::Slip => "slip",
        }
    }
}

/// Per-step inputs of one shear or torsion block, in loading order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Block {
    /// Indenter displacement from the block's start (mm or deg).
    pub load: Vec<f64>,
    /// Tangential force (N) or torque (N·mm), quasistatic, along the load.
    pub tangential: Vec<f64>,
    /// Normal force, N (for μ).
    pub normal_n: Vec<f64>,
    /// Cue (b): central-line displacement at the contact centre divided by that near the
    /// contact edge (torsion: inner over outer rotation), per step; NaN where unknown.
    pub centre_over_edge: Option<Vec<f64>>,
    /// Cue (c): contact-centre displacement (or rotation) of the gel, same unit as `load`.
    pub contact_motion: Option<Vec<f64>>,
}

/// Thresholds, each a fraction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    /// Below the initial line by more than this fraction of its rise: incipient.
    pub force_departure: f64,
    /// A step's increment below this fraction of the initial one (or negative): slip.
    pub plateau: f64,
    /// Centre over edge above (1 + this) × its value at the block's first step: incipient.
    pub centre_lead: f64,
    /// Contact motion below the indenter's by more than this fraction: incipient.
    pub lag: f64,
}

impl Thresholds {
    /// The same thresholds for a torsion block: the force cue's plateau squared. A circular
    /// contact stuck out to radius c takes a shear increment at a stiffness that grows as a
    /// power of c and a twist increment at one that grows as that power plus two: c and c³ on
    /// a half-space (Mindlin 1949, Lubkin 1951; Johnson 1985, §7.2–7.3), c² and c⁴ on a layer
    /// much thinner than c, which acts as a bed of springs. The shipped pads (contact radius
    /// over thickness 1.5 on the box, 3.1 on the portable) are nearer the thin layer, so the
    /// step whose torque increment falls to r² of the first steps' has about the stuck core of
    /// a shear step whose increment falls to r. With a gradual approach to gross slip (a
    /// pressed contact whose edge already slides inward, `mechanics::pressing`) the shear's
    /// plateau read on `portable-rotation` called slip at 4° with a fifth of the contact still
    /// stuck, two steps before the simulator's stuck fraction fell below a tenth; squared it
    /// calls it at 6°, where the simulator does.
    pub fn for_torsion(self) -> Self {
        Self {
            plateau: self.plateau.powi(2),
            ..self
        }
    }
}

impl Default for Thresholds {
    fn default() -> Self {
        Self {
            force_departure: 0.03,
            plateau: 0.25,
            centre_lead: 0.05,
            lag: 0.03,
        }
    }
}

/// One step's verdict.
#[derive(Debug, Clone, PartialEq)]
pub struct StepVerdict {
    /// Cue (a).
    pub force: State,
    /// Cue (b), if the run has frames.
    pub central_line: Option<State>,
    /// Cue (c), if the run has frames.
    pub contact: Option<State>,
    /// Combined: the force cue decides slip (it sees the whole contact), the most
    /// advanced cue decides incipient slip.
    pub state: State,
}

/// The block's result.
#[derive(Debug, Clone, PartialEq)]
pub struct SlipReport {
    /// Per step, in loading order.
    pub steps: Vec<StepVerdict>,
    /// Index of the first slipping step.
    pub onset: Option<usize>,
    /// Index of the first step with incipient slip (or slip).
    pub incipient: Option<usize>,
    /// Largest tangential-to-normal ratio up to and including the slipping steps (the
    /// static friction estimate; for torsion already converted by the caller's factor).
    pub ratio_at_slip: Option<f64>,
    /// Per cue, the first step it called incipient-or-worse, for "which cues agreed".
    pub first_by_cue: [Option<usize>; 3],
}

/// Classifies every step of a block. `None` with fewer than three steps (the initial
/// slope needs them).
pub fn classify(b: &Block, th: Thresholds) -> Option<SlipReport> {
    let n = b.load.len().min(b.tangential.len());
    if n < 3 {
        return None;
    }
    let k0 = {
        let x = [0.0, b.load[0], b.load[1]];
        let y = [0.0, b.tangential[0], b.tangential[1]];
        crate::linearity::fit_line(&x, &y, false)?.slope
    };
    let mut steps = Vec::with_capacity(n);
    let mut slipped = false;
    let mut peak = f64::NEG_INFINITY;
    // Relative to the block's first step, taken as stick: tracking near the contact
    // edge is biased by the imprint's shading, so the absolute ratio is not 1.
    let baseline = b
        .centre_over_edge
        .as_ref()
        .and_then(|v| v.iter().copied().find(|r| r.is_finite() && *r > 0.0));
    for i in 0..n {
        let (x, f) = (b.load[i], b.tangential[i]);
        let pred = k0 * x;
        let (dx, df) = if i == 0 {
            (x, f)
        } else {
            (x - b.load[i - 1], f - b.tangential[i - 1])
        };
        let stalled = i >= 2 && (df < th.plateau * k0 * dx || f < peak);
        slipped |= stalled;
        peak = peak.max(f);
        let force = if slipped {
            State::Slip
        } else if (pred - f) > th.force_departure * pred.abs() {
            State::Incipient
        } else {
            State::Stick
        };
        let central_line = b
            .centre_over_edge
            .as_ref()
            .and_then(|v| v.get(i))
            .and_then(|&r| {
                let base = baseline?;
                r.is_finite()
                    .then_some(if r > base * (1.0 + th.centre_lead) {
                        State::Incipient
                    } else {
                        State::Stick
                    })
            });
        let contact = b.contact_motion.as_ref().and_then(|v| {
            let u = *v.get(i)?;
            if !u.is_finite() || x.abs() < 1e-12 {
                return None;
            }
            let du = if i == 0 {
                u
            } else {
                u - v.get(i - 1).copied().unwrap_or(f64::NAN)
            };
            Some(
                if i >= 2 && du.is_finite() && du.abs() < th.plateau * dx.abs() {
                    State::Slip
                } else if u / x < 1.0 - th.lag {
                    State::Incipient
                } else {
                    State::Stick
                },
            )
        });
        let mut state = force;
        if state != State::Slip {
            for s in [central_line, contact].into_iter().flatten() {
                if s != State::Stick {
                    state = State::Incipient;
                }
            }
        }
        steps.push(StepVerdict {
            force,
            central_line,
            contact,
            state,
        });
    }
    let first = |f: &dyn Fn(&StepVerdict) -> bool| steps.iter().position(f);
    let onset = first(&|s| s.state == State::Slip);
    let incipient = first(&|s| s.state != State::Stick);
    let first_by_cue = [
        first(&|s| s.force != State::Stick),
        first(&|s| s.central_line.is_some_and(|c| c != State::Stick)),
        first(&|s| s.contact.is_some_and(|c| c != State::Stick)),
    ];
    let ratio_at_slip = onset.map(|k| {
        (0..=k)
            .filter(|&i| b.normal_n.get(i).is_some_and(|p| p.abs() > 1e-9))
            .map(|i| (b.tangential[i] / b.normal_n[i]).abs())
            .fold(0.0, f64::max)
    });
    Some(SlipReport {
        steps,
        onset,
        incipient,
        ratio_at_slip,
        first_by_cue,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Linear to 0.3, bending smoothly towards a plateau of 3.0, dropping at 0.8
    /// (stick–slip).
    fn block() -> Block {
        let load: Vec<f64> = (1..=20).map(|i| 0.05 * i as f64).collect();
        let tangential = load
            .iter()
            .map(|&x| {
                if x <= 0.3 + 1e-9 {
                    5.0 * x
                } else if x < 0.8 - 1e-9 {
                    1.5 + 1.5 * (1.0 - (-(x - 0.3) / 0.3).exp())
                } else {
                    2.7
                }
            })
            .collect();
        Block {
            normal_n: vec![5.0; load.len()],
            load,
            tangential,
            ..Default::default()
        }
    }

    #[test]
    fn force_cue_finds_incipient_slip_and_the_drop() {
        let b = block();
        let r = classify(&b, Thresholds::default()).expect("block");
        // 3.75 % below the initial line at 0.4 (index 7); 1.1 % at 0.35.
        assert_eq!(r.incipient, Some(7), "{:?}", r.steps);
        // The increment falls below a quarter of the initial one at 0.75 (index 14).
        assert_eq!(r.onset, Some(14));
        let mu = r.ratio_at_slip.expect("slips");
        let peak = 1.5 + 1.5 * (1.0 - (-0.45f64 / 0.3).exp());
        assert!((mu - peak / 5.0).abs() < 1e-9, "{mu}");
        assert_eq!(r.first_by_cue[1], None);
    }

    /// A twist's torque bends over more slowly than a shear force for the same stuck core
    /// (on a thin layer, increments as (c/a)⁴ where a shear's fall as (c/a)²). Read with the
    /// shear's plateau the twist "slips" while c/a is still 0.65; with the torsion
    /// thresholds when the core is as small as the shear's plateau means (c/a below 0.5).
    #[test]
    fn a_twist_is_judged_by_the_same_stuck_core_as_a_shear() {
        // The stuck core's radius over the contact's at each degree of twist; each degree's
        // torque increment is its fourth power.
        let core = [1.0, 1.0, 0.85, 0.75, 0.65, 0.55, 0.45, 0.35, 0.25, 0.15f64];
        let load: Vec<f64> = (1..=10).map(f64::from).collect();
        let tangential: Vec<f64> = core
            .iter()
            .scan(0.0, |t, c| {
                *t += c.powi(4);
                Some(*t)
            })
            .collect();
        let b = Block {
            normal_n: vec![1.0; load.len()],
            load,
            tangential,
            ..Default::default()
        };
        let shear = classify(&b, Thresholds::default()).expect("block");
        let twist = classify(&b, Thresholds::default().for_torsion()).expect("block");
        // Increments 0.52, 0.32, 0.18 (index 4, c/a 0.65: below the shear's quarter), 0.09,
        // 0.04 (index 6, c/a 0.45: below its square).
        assert_eq!(shear.onset, Some(4), "{:?}", shear.steps);
        assert_eq!(twist.onset, Some(6), "{:?}", twist.steps);
    }

    #[test]
    fn field_cues_see_incipient_slip_before_the_force_does() {
        let mut b = block();
        // Contact lags from index 3 (0.2 mm); the centre leads the edge from index 4.
        b.contact_motion = Some(
            b.load
                .iter()
                .map(|&x| {
                    if x < 0.175 {
                        x
                    } else {
                        0.15 + 0.5 * (x - 0.15)
                    }
                })
                .collect(),
        );
        b.centre_over_edge = Some(
            b.load
                .iter()
                .map(|&x| if x < 0.225 { 1.0 } else { 1.2 })
                .collect(),
        );
        let r = classify(&b, Thresholds::default()).expect("block");
        assert_eq!(r.first_by_cue[2], Some(3));
        assert_eq!(r.first_by_cue[1], Some(4));
        assert_eq!(r.incipient, Some(3));
        assert_eq!(r.onset, Some(14));
        assert!(
            classify(
                &Block {
                    load: vec![0.1, 0.2],
                    tangential: vec![1.0, 2.0],
                    ..Default::default()
                },
                Thresholds::default()
            )
            .is_none()
        );
    }
}
