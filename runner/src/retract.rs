//! The exit every run takes: stop everything, retract the pressing axes first, then the
//! others, each group with a deadline from distance and speed; record where they ended.

use std::collections::BTreeMap;

use rig::config::AxisRole;
use rig::units::fmt_value;
use serde_json::json;

use super::Stop;
use super::exec::Exec;
use super::wait::Until;

impl Exec<'_> {
    /// Moves `group` to their retract positions together and waits until each has arrived
    /// (the same completion rule as any move), each by its deadline.
    async fn retract_group(&mut self, group: &[(AxisRole, f64)], errors: &mut Vec<String>) {
        let mut watch = Vec::new();
        for &(role, target) in group {
            let Some(ax) = self.rig.axes.get_mut(&role) else {
                continue;
            };
            let info = ax.info().clone();
            let here = match ax.status().await {
                Ok(st) if !st.referenced => {
                    errors.push(format!(
                        "{role} axis is not referenced, so it was left where it is"
                    ));
                    continue;
                }
                Ok(st) => st.position,
                Err(e) => {
                    errors.push(format!("reading {role}: {e}"));
                    continue;
                }
            };
            match ax.move_to(target, info.max_speed).await {
                Ok(()) => {
                    self.targets.insert(role, target);
                    let what = format!(
                        "the retract from {} to {} {u}",
                        fmt_value((here * 1e6).round() / 1e6),
                        fmt_value(target),
                        u = info.unit.symbol()
                    );
                    let mut d = self.deadline_for(role, target - here, info.max_speed, what);
                    d.arrival = Some(self.arrival(role, target, info.max_speed));
                    watch.push(d);
                }
                Err(e) => errors.push(format!("retracting {role}: {e}")),
            }
        }
        if watch.is_empty() {
            return;
        }
        match self.wait(&mut Until::Motion(watch)).await {
            Ok(()) => {}
            Err(Stop::Interrupted) => {
                errors.push("a second interrupt abandoned the retract".into())
            }
            Err(e) => errors.push(e.to_string()),
        }
    }

    /// Stops everything and sends each axis with a retract position there.
    pub(super) async fn retract(&mut self) -> Result<(), String> {
        self.retracting = true;
        if let Some(m) = &self.monitor {
            m.begin_retract();
        }
        self.step = 0;
        self.what = "retract".into();
        self.set_phase("retracting");
        let mut errors = Vec::new();
        let roles: Vec<AxisRole> = self.rig.axes.keys().copied().collect();
        for role in &roles {
            if let Some(ax) = self.rig.axes.get_mut(role)
                && let Err(e) = ax.stop().await
            {
                errors.push(format!("stopping {role}: {e}"));
            }
        }
        // Pressing axes first, to completion: moving a tangential axis while the indenter
        // still touches would drag the elastomer.
        for pressing in [true, false] {
            let order: Vec<(AxisRole, f64)> = self
                .retract_to
                .iter()
                .filter(|(r, _)| r.presses() == pressing)
                .map(|(r, v)| (*r, *v))
                .collect();
            self.retract_group(&order, &mut errors).await;
            if self.cancel.count() >= 2 {
                break;
            }
        }
        let mut finals = BTreeMap::new();
        for role in &roles {
            if let Some(ax) = self.rig.axes.get_mut(role)
                && let Ok(st) = ax.status().await
            {
                finals.insert(role.to_string(), (st.position * 1e6).round() / 1e6);
            }
        }
        let t = self.now();
        let _ = self.rec.journal(
            t,
            "retract",
            json!({ "final_positions": finals, "errors": errors }),
            true,
        );
        let _ = self
            .rec
            .update_manifest(|m| m.final_positions = finals.clone());
        if errors.is_empty() {
            self.progress.note(&format!(
                "retracted: {}",
                finals
                    .iter()
                    .map(|(k, v)| format!("{k} {}", fmt_value(*v)))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
            Ok(())
        } else {
            Err(errors.join("; "))
        }
    }
}
