//! A real bench before a run: `gelrig probe` (does every device answer?) and `gelrig sim
//! serve` (twins of the rig's devices on real transports, so a rig file can be checked
//! end to end without hardware).

use std::collections::BTreeSet;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use rig::config::{AxisDriver, AxisRole, CameraDriver, ForceDriver, RigConfig};
use rig::twins::netft::{NetFtTwin, TwinParams as NetFtParams};
use rig::twins::smc100::{Smc100Twin, TwinParams as Smc100Params};
use rig::twins::zaber::{TwinParams as ZaberParams, ZaberTwin};
use rig::{Clock, ClockMode, OpenRequest, Wrench, lock, open};

/// One device's probe result.
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// Role (`normal`, `force`, `camera`, …).
    pub role: String,
    /// What it said about itself and its state, or why it failed.
    pub detail: String,
    /// Whether it answered.
    pub ok: bool,
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
    }
}

/// Opens each device of `rig` on its own and asks it for identity and state. Simulated
/// in-process devices have nothing to probe and are listed as such.
pub async fn probe(rig: &RigConfig) -> Vec<Probe> {
    let mut out = Vec::new();
    for (role, cfg) in &rig.axes {
        if matches!(cfg.driver, AxisDriver::Sim | AxisDriver::Manual) {
            // Nothing answers but the operator or the in-process bench.
            out.push(Probe {
                role: role.to_string(),
                detail: format!("{:?} (nothing to probe)", cfg.driver).to_lowercase(),
                ok: true,
            });
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
                    Err(e) => Err(e.to_string()),
                },
                None => Err("not opened".into()),
            },
            Err(e) => Err(e.to_string()),
        };
        out.push(match r {
            Ok(detail) => Probe {
                role: role.to_string(),
                detail,
                ok: true,
            },
            Err(detail) => Probe {
                role: role.to_string(),
                detail,
                ok: false,
            },
        });
    }
    if let Some(f) = &rig.force {
        if matches!(f.driver, ForceDriver::Sim) {
            out.push(Probe {
                role: "force".into(),
                detail: "sim (nothing to probe)".into(),
                ok: true,
            });
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
                        Err(e) => Err(e.to_string()),
                    },
                    None => Err("not opened".into()),
                },
                Err(e) => Err(e.to_string()),
            };
            out.push(match r {
                Ok(detail) => Probe {
                    role: "force".into(),
                    detail,
                    ok: true,
                },
                Err(detail) => Probe {
                    role: "force".into(),
                    detail,
                    ok: false,
                },
            });
        }
    }
    if let Some(c) = &rig.camera {
        if matches!(c.driver, CameraDriver::Sim) {
            out.push(Probe {
                role: "camera".into(),
                detail: "sim (nothing to probe)".into(),
                ok: true,
            });
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
                        Err(e) => Err(e.to_string()),
                    },
                    None => Err("not opened".into()),
                },
                Err(e) => Err(e.to_string()),
            };
            out.push(match r {
                Ok(detail) => Probe {
                    role: "camera".into(),
                    detail,
                    ok: true,
                },
                Err(detail) => Probe {
                    role: "camera".into(),
                    detail,
                    ok: false,
                },
            });
        }
    }
    out
}

/// A stage twin and how to read its position.
enum StageTwin {
    /// With its microstep size.
    Zaber(ZaberTwin, f64),
    Smc100(Smc100Twin),
}

impl StageTwin {
    fn position(&self) -> f64 {
        match self {
            StageTwin::Zaber(t, step) => t.position_microsteps() * step,
            StageTwin::Smc100(t) => t.position_mm(),
        }
    }
}

/// Running twins of a rig's devices.
pub struct Served {
    /// The rig file with every twin's address filled in.
    pub bound: RigConfig,
    stages: Vec<(AxisRole, StageTwin)>,
    netft: Option<NetFtTwin>,
}

/// Starts a twin for every Zaber and SMC100 axis (each on a pseudo-terminal) and the Net
/// F/T box (loopback UDP and TCP) of `rig`, and returns the rig with the bound addresses.
pub fn serve(rig: &RigConfig) -> std::io::Result<Served> {
    let mut bound = rig.clone();
    let mut stages = Vec::new();
    for (role, cfg) in bound.axes.iter_mut() {
        let (lo, hi) = cfg.travel();
        let twin = match cfg.driver {
            AxisDriver::Zaber => {
                let step = cfg.microstep.unwrap_or(1.0);
                let twin = ZaberTwin::spawn(ZaberParams {
                    device: cfg.device.unwrap_or(1),
                    limits: ((lo / step).round() as i64, (hi / step).round() as i64),
                    require_checksum: cfg.checksum.unwrap_or(true),
                })?;
                cfg.port = Some(twin.path().to_string());
                StageTwin::Zaber(twin, step)
            }
            AxisDriver::Smc100 => {
                let twin = Smc100Twin::spawn(Smc100Params {
                    address: cfg.device.unwrap_or(1),
                    limits: (lo, hi),
                    home_speed: 5.0,
                })?;
                cfg.port = Some(twin.path().to_string());
                StageTwin::Smc100(twin)
            }
            _ => continue,
        };
        stages.push((*role, twin));
    }
    let mut netft = None;
    if let Some(f) = bound.force.as_mut()
        && matches!(f.driver, ForceDriver::NetFt)
    {
        let twin = NetFtTwin::spawn(NetFtParams {
            rate_hz: 1000.0,
            cal: rig::drivers::netft_rdt::CalInfo {
                force_unit: 2,
                torque_unit: 4,
                counts_per_force: 1_000_000 / 7 * 10,
                counts_per_torque: 1000,
            },
            range: f.model.range(),
            first_seq: (1, 0),
        })?;
        f.address = Some(twin.rdt_addr().to_string());
        f.calibration_port = Some(twin.calibration_addr().port());
        netft = Some(twin);
    }
    Ok(Served {
        bound,
        stages,
        netft,
    })
}

impl Served {
    /// Couples the twins until `stop`: the normal stage pressing past the rig's
    /// `sim.normal_contact` loads the Net F/T box as a linear spring of `stiffness_n_per_mm`
    /// (a stand-in for the in-process elastomer, which these twins do not yet drive).
    pub fn couple(&self, stiffness_n_per_mm: f64, contact_mm: f64, stop: &Arc<AtomicBool>) {
        while !stop.load(Ordering::Relaxed) {
            if let Some(box_) = &self.netft {
                let depth = self
                    .stages
                    .iter()
                    .find(|(r, _)| *r == AxisRole::Normal)
                    .map(|(_, t)| t.position() - contact_mm)
                    .unwrap_or(0.0);
                *lock(&box_.load) = Wrench {
                    fz_n: stiffness_n_per_mm * depth.max(0.0),
                    ..Default::default()
                };
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

/// Writes the bound rig file.
pub fn write_bound(served: &Served, path: &Path) -> std::io::Result<()> {
    let text = serde_yaml::to_string(&served.bound).map_err(std::io::Error::other)?;
    let header =
        "# Written by `gelrig sim serve`: the rig file with the twins' addresses filled in.\n";
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, format!("{header}{text}"))?;
    std::fs::rename(tmp, path)
}
