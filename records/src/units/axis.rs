//! Quantities along an axis, whose unit the axis decides: a position or step (mm, % of the
//! elastomer thickness, or deg), an axis speed, and a settle rule's rate.

use std::borrow::Cow;
use std::fmt;

use schemars::{JsonSchema, Schema, SchemaGenerator};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{Dim, deserialize_dims, fmt_value, schema_for};

/// A position, step or travel along an axis: a length (mm), a percentage of the elastomer
/// thickness, or an angle (deg). Which ones are allowed depends on the axis, which the
/// protocol checker knows and this type does not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AxisQuantity {
    /// Millimetres along a linear axis.
    Mm(f64),
    /// Percent of the elastomer thickness along a linear axis.
    Percent(f64),
    /// Degrees about a rotary axis.
    Deg(f64),
}

impl AxisQuantity {
    /// The raw number, in the unit of its variant.
    pub fn raw(self) -> f64 {
        match self {
            AxisQuantity::Mm(v) | AxisQuantity::Percent(v) | AxisQuantity::Deg(v) => v,
        }
    }

    /// The value in the unit of an axis: mm (resolving % against `thickness_mm`) or deg.
    /// `None` when the quantity's dimension does not fit the axis.
    pub fn in_axis_unit(self, unit: AxisUnit, thickness_mm: f64) -> Option<f64> {
        match (self, unit) {
            (AxisQuantity::Mm(v), AxisUnit::Mm) => Some(v),
            (AxisQuantity::Percent(p), AxisUnit::Mm) => Some(p / 100.0 * thickness_mm),
            (AxisQuantity::Deg(v), AxisUnit::Deg) => Some(v),
            _ => None,
        }
    }

    /// The unit this quantity would put an axis in.
    pub fn natural_unit(self) -> AxisUnit {
        match self {
            AxisQuantity::Deg(_) => AxisUnit::Deg,
            _ => AxisUnit::Mm,
        }
    }
}

impl fmt::Display for AxisQuantity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AxisQuantity::Mm(v) => write!(f, "{} mm", fmt_value(*v)),
            AxisQuantity::Percent(v) => write!(f, "{} %", fmt_value(*v)),
            AxisQuantity::Deg(v) => write!(f, "{} deg", fmt_value(*v)),
        }
    }
}

impl Serialize for AxisQuantity {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for AxisQuantity {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let p = deserialize_dims(d, &[Dim::Length, Dim::Percent, Dim::Angle])?;
        Ok(match p.dim {
            Dim::Percent => AxisQuantity::Percent(p.value),
            Dim::Angle => AxisQuantity::Deg(p.value),
            _ => AxisQuantity::Mm(p.value),
        })
    }
}

impl JsonSchema for AxisQuantity {
    fn schema_name() -> Cow<'static, str> {
        "AxisQuantity".into()
    }
    fn json_schema(_: &mut SchemaGenerator) -> Schema {
        schema_for(
            "AxisQuantity",
            "a position or step along an axis: mm or µm on a linear axis, % of the elastomer \
             thickness on a linear axis, or deg on a rotary axis"
                .into(),
            "0.084 mm",
        )
    }
}

/// The speed of an axis move: mm/s on a linear axis, deg/s on a rotary axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisSpeed {
    /// Value in mm/s or deg/s.
    pub value: f64,
    /// Which of the two.
    pub unit: AxisUnit,
}

impl fmt::Display for AxisSpeed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}/s", fmt_value(self.value), self.unit.symbol())
    }
}

impl Serialize for AxisSpeed {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for AxisSpeed {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let p = deserialize_dims(d, &[Dim::Speed, Dim::AngularSpeed])?;
        Ok(AxisSpeed {
            value: p.value,
            unit: if p.dim == Dim::AngularSpeed {
                AxisUnit::Deg
            } else {
                AxisUnit::Mm
            },
        })
    }
}

impl JsonSchema for AxisSpeed {
    fn schema_name() -> Cow<'static, str> {
        "AxisSpeed".into()
    }
    fn json_schema(_: &mut SchemaGenerator) -> Schema {
        schema_for(
            "AxisSpeed",
            "a speed: mm/s, µm/s or mm/min on a linear axis, deg/s on a rotary axis".into(),
            "0.5 mm/s",
        )
    }
}

/// A settling threshold: a force rate (N/s) for force signals or a torque rate (N·mm/s)
/// for torque signals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettleRate {
    /// N/s.
    Force(f64),
    /// N·mm/s.
    Torque(f64),
}

impl SettleRate {
    /// The value in N/s or N·mm/s.
    pub fn value(self) -> f64 {
        match self {
            SettleRate::Force(v) | SettleRate::Torque(v) => v,
        }
    }
}

impl fmt::Display for SettleRate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SettleRate::Force(v) => write!(f, "{} N/s", fmt_value(*v)),
            SettleRate::Torque(v) => write!(f, "{} N·mm/s", fmt_value(*v)),
        }
    }
}

impl Serialize for SettleRate {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for SettleRate {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let p = deserialize_dims(d, &[Dim::ForceRate, Dim::TorqueRate])?;
        Ok(if p.dim == Dim::TorqueRate {
            SettleRate::Torque(p.value)
        } else {
            SettleRate::Force(p.value)
        })
    }
}

impl JsonSchema for SettleRate {
    fn schema_name() -> Cow<'static, str> {
        "SettleRate".into()
    }
    fn json_schema(_: &mut SchemaGenerator) -> Schema {
        schema_for(
            "SettleRate",
            "a settling threshold: N/s for a force signal, N·mm/s for a torque signal".into(),
            "0.002 N/s",
        )
    }
}

/// The unit an axis moves in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisUnit {
    /// Linear axis, millimetres.
    Mm,
    /// Rotary axis, degrees.
    Deg,
}

impl AxisUnit {
    /// `mm` or `deg`.
    pub fn symbol(self) -> &'static str {
        match self {
            AxisUnit::Mm => "mm",
            AxisUnit::Deg => "deg",
        }
    }
}
