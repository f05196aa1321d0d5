//! Scoring marker identity on synthetic scenes with exact truth (`simbench::scenes`).
//!
//! Shared by the identity tests and the accuracy-table example, so the table and the tests
//! measure the same thing:
//!
//! - **identity**: among rows a tracker reports as measured (`tracked`, `border`, `merged`),
//!   the share within 0.3 spacing of its own marker's true centre (a neighbour's identity is
//!   a spacing away);
//! - **measured**: among markers known from the reference whose true centre lies whole in
//!   view, the share reported measured (not predicted, ambiguous, lost);
//! - **rms**: position error of correct `tracked` rows of whole markers;
//! - **rest**: largest reported displacement of a measured marker in the last frame, when the
//!   motion ends at rest.
#![allow(dead_code)]

use std::time::Instant;

use simbench::{Look, MarkerLayout, Motion, Scene};
use tracking::{MarkerState, Method, Pipeline, RgbView, TrackParams};

/// The box sensor's grid (18 × 16 dots of 1.4 mm at 2.52 mm).
pub(crate) fn box_grid() -> MarkerLayout {
    MarkerLayout::Grid {
        columns: 18,
        rows: 16,
        spacing_mm: 2.52,
        diameter_mm: 1.4,
    }
}

/// The portable sensor's random triangles.
pub(crate) fn triangles() -> MarkerLayout {
    MarkerLayout::Random {
        spacing_mm: 2.0,
        size_mm: 0.7,
    }
}

/// A scored condition: a sensor, a motion and a look.
pub(crate) struct Condition {
    /// Row label.
    pub(crate) name: String,
    /// The scene.
    pub(crate) scene: Scene,
    /// The motion.
    pub(crate) motion: Motion,
    /// The look of the frames after the reference.
    pub(crate) look: Look,
    /// The look of the reference frame: the same, but at the nominal exposure (an exposure
    /// change is a change against the reference).
    pub(crate) reference_look: Look,
}

impl Condition {
    /// The box grid at `size` with `overscan` spacings of markers beyond its own layout.
    pub(crate) fn grid(name: impl Into<String>, size: (u32, u32), overscan: u32) -> Self {
        Self {
            name: name.into(),
            scene: Scene::new(&box_grid(), (45.36, 40.32), size, overscan),
            motion: Motion::Rest { frames: 1 },
            look: Look::default(),
            reference_look: Look::default(),
        }
    }

    /// The portable sensor's triangles at 640×480 (about 70 in view, 64 px apart).
    pub(crate) fn triangles(name: impl Into<String>, overscan: u32) -> Self {
        Self::triangles_over(name, (20.0, 15.0), overscan)
    }

    /// Random triangles 2 mm apart seen over `view_mm` at 640×480 ((40, 30): about 300 in
    /// view, 32 px apart, as dense as the box grid).
    pub(crate) fn triangles_over(
        name: impl Into<String>,
        view_mm: (f64, f64),
        overscan: u32,
    ) -> Self {
        Self {
            name: name.into(),
            scene: Scene::new(&triangles(), view_mm, (640, 480), overscan),
            motion: Motion::Rest { frames: 1 },
            look: Look::default(),
            reference_look: Look::default(),
        }
    }

    /// With this motion.
    pub(crate) fn moving(mut self, motion: impl FnOnce(&Scene) -> Motion) -> Self {
        self.motion = motion(&self.scene);
        self
    }

    /// With this look.
    pub(crate) fn looking(mut self, look: Look) -> Self {
        self.look = look;
        self.reference_look = Look {
            exposure: 1.0,
            ..look
        };
        self
    }

    /// With this noise seed.
    pub(crate) fn seeded(mut self, seed: u64) -> Self {
        self.look.seed = seed;
        self.reference_look.seed = seed.wrapping_add(1);
        self
    }

    /// Spacing, px.
    pub(crate) fn spacing(&self) -> f64 {
        self.scene.spacing_px()
    }

    /// The centre of the view, px.
    pub(crate) fn centre(&self) -> [f64; 2] {
        let (w, h) = self.scene.size();
        [w as f64 / 2.0 - 0.5, h as f64 / 2.0 - 0.5]
    }
}

/// What a method scored on a condition.
#[derive(Debug, Clone, Default)]
pub(crate) struct Score {
    /// Rows reported measured.
    pub(crate) claimed: usize,
    /// Of those, with a neighbour's (or no marker's) identity.
    pub(crate) wrong: usize,
    /// Whole, known markers in view.
    pub(crate) visible: usize,
    /// Of those, reported measured.
    pub(crate) measured: usize,
    /// Of those, reported ambiguous.
    pub(crate) ambiguous: usize,
    /// Σ squared error of correct tracked rows, px², and their count.
    pub(crate) sq_err: f64,
    /// Count of the rows in `sq_err`.
    pub(crate) n_err: usize,
    /// Largest displacement of a measured marker in the last frame, px (motions ending at
    /// rest).
    pub(crate) rest_px: f64,
    /// Tracking time per frame, ms (detection and identity, no rendering).
    pub(crate) ms_per_frame: f64,
    /// Reference refused.
    pub(crate) refused: Option<String>,
}

impl Score {
    /// Share of measured rows with the right identity.
    pub(crate) fn identity(&self) -> f64 {
        if self.claimed == 0 {
            1.0
        } else {
            1.0 - self.wrong as f64 / self.claimed as f64
        }
    }

    /// Share of visible markers measured.
    pub(crate) fn recall(&self) -> f64 {
        if self.visible == 0 {
            0.0
        } else {
            self.measured as f64 / self.visible as f64
        }
    }

    /// RMS error of correct tracked rows, px.
    pub(crate) fn rms(&self) -> f64 {
        (self.sq_err / self.n_err.max(1) as f64).sqrt()
    }
}

/// Runs `method` over the condition's frames (frame 0 the reference).
pub(crate) fn score(c: &Condition, method: Method) -> Score {
    score_with(c, method, &TrackParams::default())
}

/// [`score`] with explicit parameters.
pub(crate) fn score_with(c: &Condition, method: Method, params: &TrackParams) -> Score {
    let (w, h) = c.scene.size();
    let (w, h) = (w as usize, h as usize);
    let s = c.spacing();
    let (rgb, rest) = c.scene.frame(&c.motion, 0, &c.reference_look);
    let view = RgbView::new(w, h, &rgb).expect("frame size");
    let mut out = Score::default();
    let mut pipeline = match Pipeline::new(view, params, method) {
        Ok(p) => p,
        Err(e) => {
            out.refused = Some(e.to_string());
            return out;
        }
    };
    // Tracker id → printed marker (nearest at rest, within 0.3 spacing).
    let ids: Vec<Option<usize>> = pipeline
        .tracker()
        .reference_px()
        .iter()
        .map(|p| {
            (0..rest.len())
                .min_by(|&a, &b| dist(rest[a], *p).total_cmp(&dist(rest[b], *p)))
                .filter(|&t| dist(rest[t], *p) < 0.3 * s)
        })
        .collect();
    let radius = c.scene.radius_px();
    let whole = |p: [f64; 2]| {
        let m = radius + 2.0;
        p[0] > m && p[1] > m && p[0] < w as f64 - 1.0 - m && p[1] < h as f64 - 1.0 - m
    };
    let frames = c.motion.frames();
    let mut seconds = 0.0;
    for k in 1..frames {
        let (rgb, truth) = c.scene.frame(&c.motion, k, &c.look);
        let view = RgbView::new(w, h, &rgb).expect("frame size");
        let t0 = Instant::now();
        pipeline.track(view).expect("same size");
        seconds += t0.elapsed().as_secs_f64();
        let tracker = pipeline.tracker();
        for (id, t) in ids.iter().enumerate() {
            let state = tracker.states()[id];
            let p = tracker.positions_px()[id];
            let truth_p = t.map(|t| truth[t]);
            if state.is_measured() {
                out.claimed += 1;
                match truth_p {
                    Some(q) if dist(p, q) < 0.3 * s => {
                        if state == MarkerState::Tracked && whole(q) {
                            out.sq_err += (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
                            out.n_err += 1;
                        }
                    }
                    _ => out.wrong += 1,
                }
            }
            if let Some(q) = truth_p
                && whole(q)
            {
                out.visible += 1;
                if state.is_measured() {
                    out.measured += 1;
                } else if state == MarkerState::Ambiguous {
                    out.ambiguous += 1;
                }
            }
        }
        if k == frames - 1 {
            out.rest_px = (0..tracker.len())
                .filter(|&id| tracker.states()[id].is_measured())
                .map(|id| {
                    let d = tracker.displacement_px(id);
                    d[0].hypot(d[1])
                })
                .fold(0.0, f64::max);
        }
    }
    out.ms_per_frame = 1e3 * seconds / (frames.max(2) - 1) as f64;
    out
}

/// Distance between two points, px.
pub(crate) fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// A unit vector at `deg` degrees (x right, y down).
pub(crate) fn dir(deg: f64) -> [f64; 2] {
    let a = deg.to_radians();
    [a.cos(), a.sin()]
}

/// The conditions of the accuracy table: every motion and look the tracker must survive.
pub(crate) fn conditions() -> Vec<Condition> {
    let mut out = Vec::new();
    for f in [0.15, 0.25, 0.35, 0.5] {
        out.push(
            Condition::grid(
                format!("pan {f} spacing/frame, markers entering"),
                (640, 480),
                3,
            )
            .moving(|s| {
                let d = dir(20.0);
                Motion::PanAndReturn {
                    step_px: [f * s.spacing_px() * d[0], f * s.spacing_px() * d[1]],
                    frames: 8,
                }
            }),
        );
    }
    for deg in [15.0, 20.0] {
        out.push(
            Condition::grid(format!("twist {deg}° in one frame"), (640, 480), 3).moving(|s| {
                Motion::Twist {
                    centre_px: [319.5, 239.5],
                    radius_px: 3.0 * s.spacing_px(),
                    angle_rad: f64::to_radians(deg),
                    hold: 2,
                }
            }),
        );
    }
    out.push(
        Condition::grid("whole-view rotation 5°/frame", (640, 480), 3).moving(|_| Motion::Rotate {
            centre_px: [319.5, 239.5],
            rad_per_frame: 5f64.to_radians(),
            frames: 5,
        }),
    );
    out.push(
        Condition::grid("grid: 1-spacing jump", (640, 480), 0).moving(|s| Motion::Jump {
            by_px: [s.spacing_px(), 0.0],
            hold: 2,
        }),
    );
    out.push(
        Condition::triangles("triangles: 1-spacing jump", 2).moving(|s| Motion::Jump {
            by_px: [s.spacing_px(), 0.0],
            hold: 2,
        }),
    );
    for f in [0.25, 0.4, 0.5] {
        out.push(
            Condition::grid(format!("jump from rest {f} spacing"), (640, 480), 3).moving(|s| {
                let d = dir(30.0);
                Motion::Jump {
                    by_px: [f * s.spacing_px() * d[0], f * s.spacing_px() * d[1]],
                    hold: 2,
                }
            }),
        );
    }
    let slow = |s: &Scene| {
        let d = dir(35.0);
        Motion::PanAndReturn {
            step_px: [0.1 * s.spacing_px() * d[0], 0.1 * s.spacing_px() * d[1]],
            frames: 3,
        }
    };
    for (name, look) in [
        (
            "clean",
            Look {
                noise_sigma: 0.0,
                ..Look::default()
            },
        ),
        (
            "exposure −20 %",
            Look {
                exposure: 0.8,
                ..Look::default()
            },
        ),
        (
            "exposure −40 %",
            Look {
                exposure: 0.6,
                ..Look::default()
            },
        ),
        (
            "contrast 7 %",
            Look {
                contrast: Some(0.07),
                ..Look::default()
            },
        ),
        (
            "contrast 5 %",
            Look {
                contrast: Some(0.05),
                ..Look::default()
            },
        ),
        (
            "defocus = marker radius",
            Look {
                defocus_px: 8.3,
                ..Look::default()
            },
        ),
        (
            "noise σ 30",
            Look {
                noise_sigma: 30.0,
                ..Look::default()
            },
        ),
        (
            "noise σ 45",
            Look {
                noise_sigma: 45.0,
                ..Look::default()
            },
        ),
    ] {
        out.push(
            Condition::grid(format!("{name}, slow pan"), (640, 480), 3)
                .moving(slow)
                .looking(look),
        );
    }
    out.push(
        Condition::grid("1280×960, defocus = marker radius", (1280, 960), 3)
            .moving(slow)
            .looking(Look {
                defocus_px: 16.6,
                ..Look::default()
            }),
    );
    out
}

/// Steps of `f` spacings per frame along `deg`, `n` frames out and `n` back (ends at rest).
fn out_and_back(s: &Scene, deg: f64, f: f64, n: usize) -> Motion {
    let d = dir(deg);
    let step = [f * s.spacing_px() * d[0], f * s.spacing_px() * d[1]];
    let back = [-step[0], -step[1]];
    let steps: Vec<[f64; 2]> = std::iter::repeat_n(step, n)
        .chain(std::iter::repeat_n(back, n))
        .collect();
    Motion::from_steps(&steps)
}

/// Steps of the given sizes (spacings per frame, signed) along `deg`.
fn along(s: &Scene, deg: f64, sizes: &[f64]) -> Motion {
    let d = dir(deg);
    let k = s.spacing_px();
    let steps: Vec<[f64; 2]> = sizes.iter().map(|f| [f * k * d[0], f * k * d[1]]).collect();
    Motion::from_steps(&steps)
}

/// Which sensor a coming-back condition uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Pattern {
    /// The box grid, three spacings of markers beyond the view on every side.
    Grid,
    /// Random triangles as dense as the grid (about 300 in view), beyond the view too.
    Triangles,
}

impl Pattern {
    fn condition(self, name: String, seed: u64) -> Condition {
        match self {
            Self::Grid => Condition::grid(name, (640, 480), 3),
            Self::Triangles => Condition::triangles_over(name, (40.0, 30.0), 3),
        }
        .seeded(seed)
    }

    fn label(self) -> &'static str {
        match self {
            Self::Grid => "grid",
            Self::Triangles => "triangles",
        }
    }
}

/// Pans that come back, reversals, accelerations and whole-spacing jumps — the motions of
/// a grasp that lifts and lowers — with markers leaving and entering the view. The `seed`
/// picks the directions (one along a lattice axis, where a pan of half a spacing per frame
/// is exactly ambiguous, and two at random) and the sensor noise: thresholds are tuned on
/// seed 1 and reported and tested on seeds 2 and 3.
pub(crate) fn coming_back(pattern: Pattern, seed: u64) -> Vec<Condition> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(0xC0_11EB ^ seed);
    let axis = 90.0 * (seed % 4) as f64;
    let dirs = [
        axis,
        rng.random_range(0.0..360.0),
        rng.random_range(0.0..360.0),
    ];
    let p = pattern.label();
    let mut out = Vec::new();
    for (k, &deg) in dirs.iter().enumerate() {
        let noise = seed.wrapping_mul(1000).wrapping_add(k as u64);
        for f in [0.1f64, 0.2, 0.3, 0.4, 0.5] {
            // Out to about 1.6 spacings and back.
            let n = (1.6 / f).round() as usize;
            out.push(
                pattern
                    .condition(
                        format!("{p}: pan {f}/frame at {deg:.0}° out and back"),
                        noise,
                    )
                    .moving(|s| out_and_back(s, deg, f, n)),
            );
        }
        out.push(
            pattern
                .condition(
                    format!("{p}: reversals mid-pan 0.3/frame at {deg:.0}°"),
                    noise,
                )
                .moving(|s| {
                    let sizes: Vec<f64> = [(0.3, 5), (-0.3, 3), (0.3, 4), (-0.3, 6)]
                        .iter()
                        .flat_map(|&(f, n)| std::iter::repeat_n(f, n))
                        .collect();
                    along(s, deg, &sizes)
                }),
        );
        out.push(
            pattern
                .condition(
                    format!("{p}: acceleration 0.1→0.4/frame at {deg:.0}°"),
                    noise,
                )
                .moving(|s| along(s, deg, &[0.1, 0.2, 0.3, 0.4, -0.4, -0.3, -0.2, -0.1])),
        );
    }
    out
}

/// What a whole-spacing jump leaves in the frames for a tracker to see.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Seen {
    /// Only the true placement explains the frames (random triangles, or a grid whose edge
    /// is in view): the jump must be tracked.
    Decidable,
    /// The frame after the jump is the same image as the one before it (a grid larger than
    /// the view by more than the jump): no tracker can see the jump.
    SameImage,
    /// The frames differ, but a smaller jump explains every frame since the reference as
    /// well (a grid one column larger than the view, jumping two): the smaller is taken,
    /// as the rule says.
    SmallerAlias,
}

/// Whole-spacing jumps of 1.0 and 2.0 spacings from rest, held three frames, then back.
/// Grids jump along a lattice axis (the jump is a lattice vector; the seed picks which),
/// over the box grid three spacings larger than the view (whose lattice ends 1.3 spacings
/// beyond the view in x and 3 in y) and over the box grid one spacing larger, whose edges
/// are in view; triangles jump in a direction the seed picks.
pub(crate) fn jumps(pattern: Pattern, seed: u64) -> Vec<(Condition, Seen)> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x1E_A9 ^ seed);
    let mut out = Vec::new();
    for by in [1.0f64, 2.0] {
        let deg = match pattern {
            Pattern::Grid => 90.0 * (seed % 4) as f64,
            Pattern::Triangles => rng.random_range(0.0..360.0),
        };
        let seen = match pattern {
            Pattern::Triangles => Seen::Decidable,
            // Along y, three rows beyond the view hide jumps of one and two rows.
            Pattern::Grid if seed % 2 == 1 || by < 2.0 => Seen::SameImage,
            Pattern::Grid => Seen::SmallerAlias,
        };
        let c = pattern
            .condition(
                format!(
                    "{p}: jump of {by} spacing at {deg:.0}°",
                    p = pattern.label()
                ),
                seed,
            )
            .moving(|s| {
                let d = dir(deg);
                Motion::Jump {
                    by_px: [by * s.spacing_px() * d[0], by * s.spacing_px() * d[1]],
                    hold: 3,
                }
            });
        out.push((c, seen));
    }
    if pattern == Pattern::Grid {
        for by in [1.0, 2.0] {
            let deg = 180.0 * (seed % 2) as f64;
            let c = Condition::grid(
                format!("grid, edges in view: jump of {by} spacing at {deg:.0}°"),
                (640, 480),
                1,
            )
            .seeded(seed)
            .moving(|s| Motion::Jump {
                by_px: [by * s.spacing_px() * dir(deg)[0], 0.0],
                hold: 3,
            });
            out.push((c, Seen::Decidable));
        }
    }
    out
}
