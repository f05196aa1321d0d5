//! How the bench's indenter meets its gel, wherever a model of that contact is needed: the
//! simulated bench presses by it, and `gelrig fit-material` fits a bench's recorded runs with
//! it. A real bench has no `sim:` section, so its rig file says it here (`contact:`); a
//! simulated one may say it in either place, and the two must agree.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{ConfigIssue, RigConfig, YamlPath};

/// The contact model of a bench (`contact:` in a rig file).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactModelConfig {
    /// Whether the indenter's face holds the gel where it touches (true: a dry acrylic or
    /// metal face on silicone, whose μ of about 0.6 keeps a pressed face stuck) or slides on
    /// it freely (false: a lubricated face). Stuck, a flat punch presses 9–39 % harder than
    /// frictionless on the shipped punches, and the field around it is smaller per newton,
    /// so a fit of the gel's modulus is as far off as the model is wrong. Default
    /// [`PRESSING_FRICTION_DEFAULT`] (true).
    #[serde(default)]
    pub pressing_friction: Option<bool>,
    /// Whether flat punches press the gel at finite strain (neo-Hookean stiffening: 29 % at
    /// 20 % strain on the portable punch). Default false: small strain, as the thesis
    /// measured its flat punch (force linear in depth).
    #[serde(default)]
    pub finite_strain: Option<bool>,
}

/// Whether a bench presses with friction when its rig file does not say (see
/// [`ContactModelConfig::pressing_friction`]): a gel of the protocols' μ sticks under pure
/// pressing.
pub const PRESSING_FRICTION_DEFAULT: bool = true;

impl RigConfig {
    /// Whether this bench's indenter presses with friction: `sim: {pressing_friction}`, or
    /// `contact: {pressing_friction}`, or [`PRESSING_FRICTION_DEFAULT`].
    pub fn presses_with_friction(&self) -> bool {
        self.stated(|s| s.pressing_friction, |c| c.pressing_friction)
            .unwrap_or(PRESSING_FRICTION_DEFAULT)
    }

    /// How finely a simulated bench solves its contact: `sim: {fidelity}`, or the default.
    pub fn fidelity(&self) -> super::Fidelity {
        self.sim
            .as_ref()
            .and_then(|s| s.fidelity)
            .unwrap_or_default()
    }

    /// Whether this bench's flat punches press at finite strain: `sim: {finite_strain}`, or
    /// `contact: {finite_strain}`, or false.
    pub fn finite_strain(&self) -> bool {
        self.stated(|s| s.finite_strain, |c| c.finite_strain)
            .unwrap_or(false)
    }

    /// A contact-model value as `sim:` states it, or else as `contact:` does.
    fn stated(
        &self,
        in_sim: impl Fn(&super::SimConfig) -> Option<bool>,
        in_contact: impl Fn(&ContactModelConfig) -> Option<bool>,
    ) -> Option<bool> {
        self.sim
            .as_ref()
            .and_then(in_sim)
            .or(self.contact.as_ref().and_then(in_contact))
    }

    /// A model stated twice, differently, in `sim:` and `contact:`.
    pub(super) fn check_contact_model(&self) -> Vec<ConfigIssue> {
        let (Some(sim), Some(contact)) = (&self.sim, &self.contact) else {
            return Vec::new();
        };
        [
            (
                "pressing_friction",
                sim.pressing_friction,
                contact.pressing_friction,
            ),
            ("finite_strain", sim.finite_strain, contact.finite_strain),
        ]
        .into_iter()
        .filter_map(|(key, s, c)| match (s, c) {
            (Some(s), Some(c)) if s != c => Some(ConfigIssue {
                path: YamlPath::root().key("contact").key(key),
                message: format!("`contact: {{{key}: {c}}}` contradicts `sim: {{{key}: {s}}}`"),
                fix: format!("state `{key}` once, under `contact:`"),
            }),
            _ => None,
        })
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig(text: &str) -> RigConfig {
        RigConfig::from_yaml_str(text).expect("parses")
    }

    #[test]
    fn a_real_bench_states_its_contact_model_without_a_sim_section() {
        let real = rig("name: bench\ncontact: {pressing_friction: false, finite_strain: true}\n");
        assert!(real.sim.is_none());
        assert!(!real.presses_with_friction());
        assert!(real.finite_strain());
        assert!(real.check().is_empty(), "{:?}", real.check());
        let silent = rig("name: bench\n");
        assert_eq!(silent.presses_with_friction(), PRESSING_FRICTION_DEFAULT);
        assert!(!silent.finite_strain());
    }

    #[test]
    fn a_model_stated_twice_must_agree() {
        let sim = "sim: {normal_contact: 10 mm, pressing_friction: true}";
        let agree = rig(&format!(
            "name: b\n{sim}\ncontact: {{pressing_friction: true, finite_strain: true}}\n"
        ));
        assert!(agree.check().is_empty(), "{:?}", agree.check());
        assert!(agree.presses_with_friction() && agree.finite_strain());
        let clash = rig(&format!(
            "name: b\n{sim}\ncontact: {{pressing_friction: false}}\n"
        ));
        let issues = clash.check();
        assert_eq!(issues.len(), 1, "{issues:?}");
        assert_eq!(issues[0].path.to_string(), "contact.pressing_friction");
        assert!(
            issues[0].message.contains("contradicts"),
            "{}",
            issues[0].message
        );
        let strain = rig("name: b\nsim: {normal_contact: 10 mm}\ncontact: {finite_strain: true}\n");
        assert!(strain.check().is_empty() && strain.finite_strain());
        let both = rig(
            "name: b\nsim: {normal_contact: 10 mm, finite_strain: false, pressing_friction: true}\n\
             contact: {finite_strain: true, pressing_friction: false}\n",
        );
        let paths: Vec<String> = both.check().iter().map(|i| i.path.to_string()).collect();
        assert_eq!(
            paths,
            ["contact.pressing_friction", "contact.finite_strain"]
        );
    }
}
