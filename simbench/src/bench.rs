//! A real bench before a run: `gelrig probe` (does every device answer?) and `gelrig sim
//! serve` (twins of the rig's devices on real transports, so a rig file can be checked
//! end to end without hardware).

use std::collections::BTreeSet;
use std::path::Path;

use crate::{OpenRequest, open};
use crate::{PlantSpec, TwinPlant};
use rig::config::{AxisDriver, AxisRole, CameraDriver, ForceDriver, RigConfig, TwinsConfig};
use rig::twins::modbus::{Endpoint, ModbusTwin};
use rig::twins::netft::{NetFtTwin, TwinParams as NetFtParams};
use rig::twins::smc100::{Smc100Twin, TwinParams as Smc100Params};
use rig::twins::zaber::{TwinParams as ZaberParams, ZaberTwin};
use rig::{Clock, ClockMode, RigError, STATUS_SATURATED};

/// One device's probe result.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// Role (`normal`, `force`, `camera`, …).
    pub role: String,
    /// What it said about itself and its state, or why it failed.
    pub detail: String,
    /// Whether it answered and is ready.
    pub ok: bool,
    /// It did not answer at all (a timeout, a closed port); a device that answered with a
    /// refusal, "busy" or a value that cannot be is not silent.
    pub silent: bool,
}

impl Probe {
    fn from_result(role: impl Into<String>, r: Result<String, RigError>) -> Self {
        let role = role.into();
        match r {
            Ok(detail) => Self {
                role,
                detail,
                ok: true,
                silent: false,
            },
            Err(e) => Self {
                role,
                silent: matches!(e, RigError::Timeout { .. } | RigError::Io { .. }),
                detail: e.to_string(),
                ok: false,
            },
        }
    }

    fn nothing_to_probe(role: impl Into<String>, what: &str) -> Self {
        Self {
            role: role.into(),
            detail: format!("{what} (nothing to probe)"),
            ok: true,
            silent: false,
        }
    }
}

fn not_opened() -> RigError {
    RigError::Unsupported {
        device: "probe".into(),
        detail: "not opened".into(),
    }
}

fn request(axes: &[AxisRole], force: bool, camera: bool) -> OpenRequest {
    OpenRequest {
        axes: axes.iter().copied().collect::<BTreeSet<_>>(),
        force,
        camera,
        disturber: false,
        plant: None,
        clock: Clock::new(ClockMode::Monotonic),
        seed: 0,
        traction_maps_px: None,
    }
}

/// Opens each device of `rig` on its own and asks it for identity and state. Simulated
/// in-process devices have nothing to probe and are listed as such.
pub async fn probe(rig: &RigConfig) -> Vec<Probe> {
    let mut out = Vec::new();
    for (role, cfg) in &rig.axes {
        if matches!(cfg.driver, AxisDriver::Sim | AxisDriver::Manual) {
            // Nothing answers but the operator or the in-process bench.
            out.push(Probe::nothing_to_probe(
                role.to_string(),
                &format!("{:?}", cfg.driver).to_lowercase(),
            ));
            continue;
        }
        let r = match open(rig, request(&[*role], false, false)).await {
            Ok(mut opened) => match opened.axes.get_mut(role) {
                Some(a) => match a.status().await {
                    Ok(s) => Ok(format!(
                        "{}; position {:.4} {}{}{}",
                        a.info().identity,
                        s.position,
                        a.info().unit.symbol(),
                        if s.referenced {
                            ""
                        } else {
                            ", not referenced (home it)"
                        },
                        if s.moving { ", moving" } else { "" }
                    )),
                    Err(e) => Err(e),
                },
                None => Err(not_opened()),
            },
            Err(e) => Err(e),
        };
        out.push(Probe::from_result(role.to_string(), r));
    }
    if let Some(f) = &rig.force {
        if matches!(f.driver, ForceDriver::Sim) {
            out.push(Probe::nothing_to_probe("force", "sim"));
        } else {
            let r = match open(rig, request(&[], true, false)).await {
                Ok(mut o) => match o.force.as_mut() {
                    Some(s) => match s.read().await {
                        Ok(x) => Ok(format!(
                            "{}; Fz {:.3} N, Fx {:.3} N, Tz {:.2} N·mm, status {:#x}",
                            s.info().identity,
                            x.wrench.fz_n,
                            x.wrench.fx_n,
                            x.wrench.tz_nmm,
                            x.status
                        )),
                        Err(e) => Err(e),
                    },
                    None => Err(not_opened()),
                },
                Err(e) => Err(e),
            };
            out.push(Probe::from_result("force", r));
        }
    }
    if let Some(c) = &rig.camera {
        if matches!(c.driver, CameraDriver::Sim) {
            out.push(Probe::nothing_to_probe("camera", "sim"));
        } else {
            let r = match open(rig, request(&[], false, true)).await {
                Ok(mut o) => match o.camera.as_mut() {
                    Some(cam) => match cam.capture().await {
                        Ok(f) => Ok(format!(
                            "{}; frame {}×{} seq {}",
                            cam.info().identity,
                            f.width,
                            f.height,
                            f.seq
                        )),
                        Err(e) => Err(e),
                    },
                    None => Err(not_opened()),
                },
                Err(e) => Err(e),
            };
            out.push(Probe::from_result("camera", r));
        }
    }
    out
}

/// What `gelrig sim serve` simulates behind the twins.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// How many times faster than the wall the twins' stages move and the elastomer
    /// relaxes; a run against them must use the same (the bound rig file says so).
    pub time_scale: f64,
    /// The elastomer and indenter of a protocol, and the axes it moves: with it the Net
    /// F/T twin reads the same plant as a dry run; without it the box reads zero.
    pub plant: Option<(PlantSpec, BTreeSet<AxisRole>)>,
    /// Seed of the plant's noise and sensor offset.
    pub seed: u64,
    /// How the stage twins behave around a move, like real drives: BUSY shown this long
    /// after the command (plant time: divided by the time scale on the wall), and a landing this many device steps past the
    /// target (Zaber microsteps, SMC100 and Modbus steps of the axis resolution).
    pub drive_latency: std::time::Duration,
    /// See `drive_latency`.
    pub overshoot_steps: f64,
}

/// A stage's position in its axis unit (mm or deg), read from its twin.
type PositionProbe = Box<dyn Fn() -> f64 + Send>;

/// Running twins of a rig's devices; dropping it stops them.
pub struct Served {
    /// The rig file with every twin's address filled in.
    pub bound: RigConfig,
    /// What each twin is, for the operator (`normal: zaber on /dev/pts/3`).
    pub listing: Vec<String>,
    _zaber: Vec<ZaberTwin>,
    _smc100: Vec<Smc100Twin>,
    _modbus: Vec<ModbusTwin>,
    _netft: Option<NetFtTwin>,
}

/// Starts a twin for every wire device of `rig` (Zaber and SMC100 on pseudo-terminals,
/// Modbus on loopback TCP or, when the map names a `port`, RTU on a pseudo-terminal; the
/// Net F/T box on loopback UDP and TCP) and returns the rig with their addresses. Must
/// run inside a tokio runtime, which serves Modbus TCP for as long as the twins live.
pub async fn serve(rig: &RigConfig, options: ServeOptions) -> Result<Served, String> {
    let scale = options.time_scale;
    let timing = |step: f64| rig::twins::motion::Timing {
        // Plant time, like everything a twin simulates: K× faster on the wall.
        delay_before_busy: options.drive_latency.div_f64(scale.max(1e-9)),
        settle_to_in_position: std::time::Duration::from_millis(5),
        overshoot: options.overshoot_steps * step,
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(format!("time scale {scale} must be a positive number"));
    }
    let mut bound = rig.clone();
    bound.twins = Some(TwinsConfig { time_scale: scale });
    let mut listing = Vec::new();
    let mut probes: Vec<(AxisRole, PositionProbe)> = Vec::new();
    let stages = start_stage_twins(&mut bound, scale, &timing, &mut listing, &mut probes).await?;
    let netft = start_netft_twin(rig, &mut bound, options, &mut listing, probes)?;
    Ok(Served {
        bound,
        listing,
        _zaber: stages.zaber,
        _smc100: stages.smc100,
        _modbus: stages.modbus,
        _netft: netft,
    })
}

/// The stage twins of a rig, by kind.
struct StageTwins {
    zaber: Vec<ZaberTwin>,
    smc100: Vec<Smc100Twin>,
    modbus: Vec<ModbusTwin>,
}

/// Starts a twin for every wire stage of `bound` at `scale` (with the drive behaviour
/// `timing` gives for a device step), writing each twin's address into `bound`, a line for
/// the operator into `listing`, and a reader of its position into `probes`.
async fn start_stage_twins(
    bound: &mut RigConfig,
    scale: f64,
    timing: &impl Fn(f64) -> rig::twins::motion::Timing,
    listing: &mut Vec<String>,
    probes: &mut Vec<(AxisRole, PositionProbe)>,
) -> Result<StageTwins, String> {
    let (mut zaber, mut smc100, mut modbus) = (Vec::new(), Vec::new(), Vec::new());
    let fail = |role: &AxisRole, e: std::io::Error| format!("{role}: starting its twin: {e}");
    for (role, cfg) in bound.axes.iter_mut() {
        let (lo, hi) = cfg.travel();
        match cfg.driver {
            AxisDriver::Zaber => {
                let step = cfg.microstep.unwrap_or(1.0);
                let twin = ZaberTwin::spawn(ZaberParams {
                    device: cfg.device.unwrap_or(1),
                    limits: ((lo / step).round() as i64, (hi / step).round() as i64),
                    require_checksum: cfg.checksum.unwrap_or(true),
                    time_scale: scale,
                })
                .map_err(|e| fail(role, e))?;
                cfg.port = Some(twin.path().to_string());
                listing.push(format!("{role}: zaber twin on {}", twin.path()));
                let at = twin.position_probe();
                probes.push((*role, Box::new(move || at() * step)));
                twin.set_timing(timing(1.0));
                zaber.push(twin);
            }
            AxisDriver::Smc100 => {
                let twin = Smc100Twin::spawn(Smc100Params {
                    address: cfg.device.unwrap_or(1),
                    limits: (lo, hi),
                    home_speed: 5.0,
                    time_scale: scale,
                })
                .map_err(|e| fail(role, e))?;
                cfg.port = Some(twin.path().to_string());
                listing.push(format!("{role}: smc100 twin on {}", twin.path()));
                probes.push((*role, Box::new(twin.position_probe())));
                twin.set_timing(timing(cfg.resolution.raw()));
                smc100.push(twin);
            }
            AxisDriver::Modbus => {
                let Some(map) = cfg.modbus.as_mut() else {
                    return Err(format!("{role}: a modbus axis needs its `modbus:` map"));
                };
                let per = map.steps_per_unit;
                let limits = ((lo * per).round() as i32, (hi * per).round() as i32);
                let (twin, kind) = if map.port.is_some() {
                    let t = ModbusTwin::spawn_rtu(map.clone(), limits, scale);
                    (t.map_err(|e| fail(role, e))?, "rtu")
                } else {
                    let t = ModbusTwin::spawn(map.clone(), limits, scale).await;
                    (t.map_err(|e| fail(role, e))?, "tcp")
                };
                match &twin.endpoint {
                    Endpoint::Tcp(a) => map.address = Some(a.to_string()),
                    Endpoint::Rtu(p) => map.port = Some(p.clone()),
                }
                listing.push(format!("{role}: modbus {kind} twin at {}", twin.address()));
                let at = twin.position_probe();
                probes.push((*role, Box::new(move || at() / per)));
                twin.set_timing(timing(1.0));
                modbus.push(twin);
            }
            AxisDriver::Sim | AxisDriver::Manual => {}
        }
    }
    Ok(StageTwins {
        zaber,
        smc100,
        modbus,
    })
}

/// Starts the Net F/T twin when `bound`'s force sensor is one, writing its addresses into
/// `bound` and a line into `listing`. With a plant in `options` it reads the simulated
/// elastomer under the stages the protocol moves (their `probes`); without, zero.
fn start_netft_twin(
    rig: &RigConfig,
    bound: &mut RigConfig,
    options: ServeOptions,
    listing: &mut Vec<String>,
    mut probes: Vec<(AxisRole, PositionProbe)>,
) -> Result<Option<NetFtTwin>, String> {
    let scale = options.time_scale;
    let Some(f) = bound.force.as_mut() else {
        return Ok(None);
    };
    if !matches!(f.driver, ForceDriver::NetFt) {
        return Ok(None);
    }
    let twin = NetFtTwin::spawn(NetFtParams {
        rate_hz: netft_rate_hz(scale),
        cal: rig::drivers::netft_rdt::CalInfo {
            force_unit: 2,
            torque_unit: 4,
            counts_per_force: 1_000_000 / 7 * 10,
            counts_per_torque: 1000,
        },
        range: f.model.range(),
        first_seq: (1, 0),
    })
    .map_err(|e| format!("force: starting the net f/t twin: {e}"))?;
    f.address = Some(twin.rdt_addr().to_string());
    f.calibration_port = Some(twin.calibration_addr().port());
    listing.push(format!(
        "force: net f/t twin at {} (calibration port {})",
        twin.rdt_addr(),
        twin.calibration_addr().port()
    ));
    if let Some((spec, axes)) = options.plant {
        let mut plant = TwinPlant::new(rig, spec, &axes, options.seed)
            .map_err(|e| format!("the simulated elastomer: {e}"))?;
        // Only the stages the protocol moves touch the elastomer.
        probes.retain(|(role, _)| axes.contains(role));
        let origin = std::time::Instant::now();
        let mut at = Vec::with_capacity(probes.len());
        twin.drive_with(Box::new(move || {
            // Plant time runs `scale` times faster than the wall, like the stages.
            let t_ns = (origin.elapsed().as_nanos() as f64 * scale) as u64;
            at.clear();
            at.extend(probes.iter().map(|(role, p)| (*role, p())));
            let (w, status) = plant.sense(&at, t_ns);
            (w, status & STATUS_SATURATED != 0)
        }));
    }
    Ok(Some(twin))
}

/// Records per wall second of the Net F/T twin: 40 per simulated second (twice the
/// protocols' usual 20 Hz force stream) so a scaled run still fills its force windows,
/// within what the real box streams (1–7 kHz, devices spec §2.1).
pub fn netft_rate_hz(time_scale: f64) -> f64 {
    (40.0 * time_scale).clamp(1000.0, 7000.0)
}

/// Writes the bound rig file (atomically: a run started meanwhile never reads half of it).
pub fn write_bound(served: &Served, path: &Path) -> std::io::Result<()> {
    let text = serde_yaml::to_string(&served.bound).map_err(std::io::Error::other)?;
    let header =
        "# Written by `gelrig sim serve`: the rig file with the twins' addresses filled in.\n";
    rundir::write::write_atomic(path, format!("{header}{text}").as_bytes())
        .map_err(std::io::Error::other)
}
