//! Quantities with explicit units, as written in protocol and rig files.
//!
//! A lab protocol that says `step: 2` is ambiguous (mm? µm? % of thickness?) and a wrong
//! guess breaks an elastomer or a sensor. So every physical value in gelrig's YAML is a
//! string with its unit — `0.084 mm`, `2 %`, `180 s`, `0.5 mm/s`, `500 N·mm` — parsed here
//! into the lab's base units, stated once:
//!
//! | dimension | base unit | accepted |
//! |---|---|---|
//! | length | mm | mm, µm (um), cm, m |
//! | fraction of elastomer thickness | % | % |
//! | angle | deg | deg, °, rad, mrad |
//! | time | s | s, ms, µs (us), min, h |
//! | force | N | N, mN |
//! | torque | N·mm | N·mm (N*mm, Nmm, N mm), N·m (Nm), mN·m |
//! | speed | mm/s | mm/s, µm/s, mm/min |
//! | angular speed | deg/s | deg/s, °/s, rad/s |
//! | frequency | Hz | Hz, kHz |
//! | force rate | N/s | N/s, mN/s |
//! | torque rate | N·mm/s | N·mm/s |
//! | pressure (modulus) | MPa | MPa, kPa, Pa |
//! | mass | g | g, kg, mg |
//!
//! A bare number, an unknown unit, or a unit of the wrong dimension is a deserialization
//! error whose message names the accepted units, so the YAML loader can point at the value.

use std::borrow::Cow;
use std::f64::consts::PI;
use std::fmt;

use schemars::{JsonSchema, Schema, SchemaGenerator, json_schema};
use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

mod axis;
pub use axis::{AxisQuantity, AxisSpeed, AxisUnit, SettleRate};

/// Physical dimension of a quantity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dim {
    /// Length, base mm.
    Length,
    /// Fraction of the elastomer thickness, base %.
    Percent,
    /// Angle, base degrees.
    Angle,
    /// Time, base seconds.
    Time,
    /// Force, base N.
    Force,
    /// Torque, base N·mm.
    Torque,
    /// Linear speed, base mm/s.
    Speed,
    /// Angular speed, base deg/s.
    AngularSpeed,
    /// Frequency, base Hz.
    Frequency,
    /// Force rate, base N/s.
    ForceRate,
    /// Torque rate, base N·mm/s.
    TorqueRate,
    /// Pressure or modulus, base MPa.
    Pressure,
    /// Mass, base g.
    Mass,
}

impl Dim {
    /// The dimension's name in error messages.
    pub fn noun(self) -> &'static str {
        match self {
            Dim::Length => "a length",
            Dim::Percent => "a percentage of the elastomer thickness",
            Dim::Angle => "an angle",
            Dim::Time => "a duration",
            Dim::Force => "a force",
            Dim::Torque => "a torque",
            Dim::Speed => "a linear speed",
            Dim::AngularSpeed => "an angular speed",
            Dim::Frequency => "a rate",
            Dim::ForceRate => "a force rate",
            Dim::TorqueRate => "a torque rate",
            Dim::Pressure => "a modulus",
            Dim::Mass => "a mass",
        }
    }

    /// The base unit's symbol.
    pub fn base_unit(self) -> &'static str {
        match self {
            Dim::Length => "mm",
            Dim::Percent => "%",
            Dim::Angle => "deg",
            Dim::Time => "s",
            Dim::Force => "N",
            Dim::Torque => "N·mm",
            Dim::Speed => "mm/s",
            Dim::AngularSpeed => "deg/s",
            Dim::Frequency => "Hz",
            Dim::ForceRate => "N/s",
            Dim::TorqueRate => "N·mm/s",
            Dim::Pressure => "MPa",
            Dim::Mass => "g",
        }
    }

    /// The accepted unit symbols, for messages.
    pub fn accepted(self) -> String {
        UNITS
            .iter()
            .filter(|u| u.dim == self)
            .map(|u| u.symbol)
            .collect::<Vec<_>>()
            .join(", ")
    }
}

struct UnitDef {
    /// The symbol shown in messages.
    symbol: &'static str,
    /// Spellings accepted after normalisation (spaces, `·` and `*` removed).
    spellings: &'static [&'static str],
    dim: Dim,
    to_base: f64,
}

const UNITS: &[UnitDef] = &[
    UnitDef {
        symbol: "mm",
        spellings: &["mm"],
        dim: Dim::Length,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "µm",
        spellings: &["µm", "μm", "um"],
        dim: Dim::Length,
        to_base: 1e-3,
    },
    UnitDef {
        symbol: "cm",
        spellings: &["cm"],
        dim: Dim::Length,
        to_base: 10.0,
    },
    UnitDef {
        symbol: "m",
        spellings: &["m"],
        dim: Dim::Length,
        to_base: 1e3,
    },
    UnitDef {
        symbol: "%",
        spellings: &["%"],
        dim: Dim::Percent,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "deg",
        spellings: &["deg", "°", "degree", "degrees"],
        dim: Dim::Angle,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "rad",
        spellings: &["rad"],
        dim: Dim::Angle,
        to_base: 180.0 / PI,
    },
    UnitDef {
        symbol: "mrad",
        spellings: &["mrad"],
        dim: Dim::Angle,
        to_base: 0.18 / PI,
    },
    UnitDef {
        symbol: "s",
        spellings: &["s", "sec"],
        dim: Dim::Time,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "ms",
        spellings: &["ms"],
        dim: Dim::Time,
        to_base: 1e-3,
    },
    UnitDef {
        symbol: "µs",
        spellings: &["µs", "μs", "us"],
        dim: Dim::Time,
        to_base: 1e-6,
    },
    UnitDef {
        symbol: "min",
        spellings: &["min"],
        dim: Dim::Time,
        to_base: 60.0,
    },
    UnitDef {
        symbol: "h",
        spellings: &["h"],
        dim: Dim::Time,
        to_base: 3600.0,
    },
    UnitDef {
        symbol: "N",
        spellings: &["N"],
        dim: Dim::Force,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "mN",
        spellings: &["mN"],
        dim: Dim::Force,
        to_base: 1e-3,
    },
    UnitDef {
        symbol: "N·mm",
        spellings: &["Nmm"],
        dim: Dim::Torque,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "N·m",
        spellings: &["Nm"],
        dim: Dim::Torque,
        to_base: 1e3,
    },
    UnitDef {
        symbol: "mN·m",
        spellings: &["mNm"],
        dim: Dim::Torque,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "mm/s",
        spellings: &["mm/s"],
        dim: Dim::Speed,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "µm/s",
        spellings: &["µm/s", "μm/s", "um/s"],
        dim: Dim::Speed,
        to_base: 1e-3,
    },
    UnitDef {
        symbol: "mm/min",
        spellings: &["mm/min"],
        dim: Dim::Speed,
        to_base: 1.0 / 60.0,
    },
    UnitDef {
        symbol: "deg/s",
        spellings: &["deg/s", "°/s"],
        dim: Dim::AngularSpeed,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "rad/s",
        spellings: &["rad/s"],
        dim: Dim::AngularSpeed,
        to_base: 180.0 / PI,
    },
    UnitDef {
        symbol: "Hz",
        spellings: &["Hz"],
        dim: Dim::Frequency,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "kHz",
        spellings: &["kHz"],
        dim: Dim::Frequency,
        to_base: 1e3,
    },
    UnitDef {
        symbol: "N/s",
        spellings: &["N/s"],
        dim: Dim::ForceRate,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "mN/s",
        spellings: &["mN/s"],
        dim: Dim::ForceRate,
        to_base: 1e-3,
    },
    UnitDef {
        symbol: "N·mm/s",
        spellings: &["Nmm/s"],
        dim: Dim::TorqueRate,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "MPa",
        spellings: &["MPa"],
        dim: Dim::Pressure,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "kPa",
        spellings: &["kPa"],
        dim: Dim::Pressure,
        to_base: 1e-3,
    },
    UnitDef {
        symbol: "Pa",
        spellings: &["Pa"],
        dim: Dim::Pressure,
        to_base: 1e-6,
    },
    UnitDef {
        symbol: "g",
        spellings: &["g"],
        dim: Dim::Mass,
        to_base: 1.0,
    },
    UnitDef {
        symbol: "kg",
        spellings: &["kg"],
        dim: Dim::Mass,
        to_base: 1e3,
    },
    UnitDef {
        symbol: "mg",
        spellings: &["mg"],
        dim: Dim::Mass,
        to_base: 1e-3,
    },
];

/// A parsed quantity: value in the base unit of its dimension.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parsed {
    /// Value in the base unit of `dim`.
    pub value: f64,
    /// The dimension the unit belongs to.
    pub dim: Dim,
}

/// Parses `"<number> <unit>"`; the message of an error says what was wrong and the fix.
pub fn parse(text: &str) -> Result<Parsed, String> {
    let s = text.trim();
    let split = number_prefix_len(s);
    if split == 0 {
        return Err(format!(
            "`{text}` does not start with a number; fix: write a value and a unit, e.g. `0.5 mm`"
        ));
    }
    let value: f64 = s[..split].parse().map_err(|_| {
        format!(
            "`{}` in `{text}` is not a number; fix: write a decimal number",
            &s[..split]
        )
    })?;
    if !value.is_finite() {
        return Err(format!(
            "`{text}` is not a finite number; fix: write a finite value"
        ));
    }
    let unit_text = s[split..].trim();
    if unit_text.is_empty() {
        return Err(format!(
            "`{text}` has no unit; fix: write it with one, e.g. `{value} mm`"
        ));
    }
    let normalised: String = unit_text
        .chars()
        .filter(|c| !c.is_whitespace() && *c != '·' && *c != '*' && *c != '⋅')
        .collect();
    match UNITS
        .iter()
        .find(|u| u.spellings.contains(&normalised.as_str()))
    {
        Some(u) => Ok(Parsed {
            value: value * u.to_base,
            dim: u.dim,
        }),
        None => {
            let best = UNITS
                .iter()
                .flat_map(|u| u.spellings.iter().map(move |sp| (u.symbol, sp)))
                .map(|(sym, sp)| (sym, strsim::levenshtein(sp, &normalised)))
                .min_by_key(|(_, d)| *d);
            let hint = match best {
                Some((sym, d)) if d <= 2 => format!("did you mean `{sym}`?"),
                _ => "use one of the units listed by `gelrig schema`".to_string(),
            };
            Err(format!(
                "unknown unit `{unit_text}` in `{text}`; fix: {hint}"
            ))
        }
    }
}

/// Length of the leading decimal number (sign, digits, point, exponent) of `s`.
fn number_prefix_len(s: &str) -> usize {
    let b = s.as_bytes();
    let mut i = 0;
    if i < b.len() && (b[i] == b'+' || b[i] == b'-') {
        i += 1;
    }
    let digits_start = i;
    while i < b.len() && b[i].is_ascii_digit() {
        i += 1;
    }
    if i < b.len() && b[i] == b'.' {
        i += 1;
        while i < b.len() && b[i].is_ascii_digit() {
            i += 1;
        }
    }
    if i == digits_start || (i == digits_start + 1 && b[digits_start] == b'.') {
        return 0;
    }
    // Exponent only if followed by digits (so `5 m` is not read as an exponent).
    if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
        let mut j = i + 1;
        if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
            j += 1;
        }
        let exp_digits = j;
        while j < b.len() && b[j].is_ascii_digit() {
            j += 1;
        }
        if j > exp_digits {
            i = j;
        }
    }
    i
}

/// Formats a base-unit value without float noise (`0.084`, not `0.08399999999999999`).
pub fn fmt_value(v: f64) -> String {
    let rounded = (v * 1e9).round() / 1e9;
    let s = format!("{rounded}");
    if s == "-0" { "0".to_string() } else { s }
}

/// Formats any value for a message: as [`fmt_value`] when ordinary, in scientific notation
/// when tiny or huge (`1e-320` must not print as `0`).
pub fn fmt_any(v: f64) -> String {
    if v.is_finite() && v.fract() == 0.0 && v.abs() < 1e16 {
        format!("{v:.0}")
    } else if v != 0.0 && (v.abs() < 1e-6 || v.abs() >= 1e9) {
        format!("{v:e}")
    } else {
        fmt_value(v)
    }
}

/// Deserializes a string quantity whose dimension must be one of `dims`.
fn deserialize_dims<'de, D: Deserializer<'de>>(
    deserializer: D,
    dims: &'static [Dim],
) -> Result<Parsed, D::Error> {
    struct V(&'static [Dim]);
    impl V {
        fn expected(&self) -> String {
            self.0
                .iter()
                .map(|d| format!("{} ({})", d.noun(), d.accepted()))
                .collect::<Vec<_>>()
                .join(" or ")
        }
        fn bare<E: de::Error>(&self, v: f64) -> E {
            E::custom(format!(
                "`{}` has no unit ({} expected); fix: write it with one, e.g. `{} {}`",
                fmt_value(v),
                self.0[0].noun(),
                fmt_value(v),
                self.0[0].base_unit()
            ))
        }
    }
    impl Visitor<'_> for V {
        type Value = Parsed;
        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "{}", self.expected())
        }
        fn visit_str<E: de::Error>(self, v: &str) -> Result<Parsed, E> {
            let p = parse(v).map_err(E::custom)?;
            if self.0.contains(&p.dim) {
                Ok(p)
            } else {
                Err(E::custom(format!(
                    "`{v}` is {}, but {} is expected here; fix: write it in {}",
                    p.dim.noun(),
                    self.expected(),
                    self.0
                        .iter()
                        .map(|d| d.base_unit())
                        .collect::<Vec<_>>()
                        .join(" or ")
                )))
            }
        }
        fn visit_f64<E: de::Error>(self, v: f64) -> Result<Parsed, E> {
            Err(self.bare(v))
        }
        fn visit_i64<E: de::Error>(self, v: i64) -> Result<Parsed, E> {
            Err(self.bare(v as f64))
        }
        fn visit_u64<E: de::Error>(self, v: u64) -> Result<Parsed, E> {
            Err(self.bare(v as f64))
        }
    }
    deserializer.deserialize_any(V(dims))
}

fn schema_for(name: &str, description: String, example: &str) -> Schema {
    json_schema!({
        "type": "string",
        "title": name,
        "description": description,
        "pattern": r"^\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*\S+\s*$",
        "examples": [example],
    })
}

/// Declares a single-dimension quantity newtype holding its base-unit value.
macro_rules! quantity {
    ($(#[$doc:meta])* $name:ident, $dim:expr, $getter:ident, $example:literal) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
        pub struct $name(f64);

        impl $name {
            /// Builds the quantity from a value in the base unit.
            pub const fn new($getter: f64) -> Self {
                Self($getter)
            }
            /// The value in the base unit named by this method.
            pub fn $getter(self) -> f64 {
                self.0
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{} {}", fmt_value(self.0), $dim.base_unit())
            }
        }

        impl Serialize for $name {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.collect_str(self)
            }
        }

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                deserialize_dims(d, &[$dim]).map(|p| Self(p.value))
            }
        }

        impl JsonSchema for $name {
            fn schema_name() -> Cow<'static, str> {
                stringify!($name).into()
            }
            fn json_schema(_: &mut SchemaGenerator) -> Schema {
                schema_for(
                    stringify!($name),
                    format!("{} with its unit: {}", $dim.noun(), $dim.accepted()),
                    $example,
                )
            }
        }
    };
}

quantity!(
    /// A length; base unit mm.
    Length, Dim::Length, mm, "9.5 mm"
);
quantity!(
    /// A duration; base unit s.
    Duration, Dim::Time, s, "180 s"
);
quantity!(
    /// A force; base unit N.
    Force, Dim::Force, n, "40 N"
);
quantity!(
    /// A torque; base unit N·mm.
    Torque, Dim::Torque, nmm, "200 N·mm"
);
quantity!(
    /// A sampling or frame rate; base unit Hz.
    Frequency, Dim::Frequency, hz, "100 Hz"
);
quantity!(
    /// A rate of change of force; base unit N/s.
    ForceRate, Dim::ForceRate, n_per_s, "0.002 N/s"
);
quantity!(
    /// A modulus; base unit MPa.
    Pressure, Dim::Pressure, mpa, "0.25 MPa"
);
quantity!(
    /// A mass; base unit g.
    Mass, Dim::Mass, g, "100 g"
);

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize, Debug)]
    struct T {
        l: Length,
        q: AxisQuantity,
        t: Torque,
    }

    #[test]
    fn parses_units_and_aliases() {
        assert_eq!(parse("0.5 mm").map(|p| p.value), Ok(0.5));
        assert_eq!(parse("500 um").map(|p| p.value), Ok(0.5));
        assert_eq!(parse("500µm").map(|p| p.value), Ok(0.5));
        assert_eq!(parse("2 %").map(|p| p.dim), Ok(Dim::Percent));
        assert_eq!(parse("3 min").map(|p| p.value), Ok(180.0));
        assert_eq!(parse("500 N·mm").map(|p| p.value), Ok(500.0));
        assert_eq!(parse("500 N*mm").map(|p| p.value), Ok(500.0));
        assert_eq!(parse("0.5 N m").map(|p| p.value), Ok(500.0));
        assert_eq!(parse("1e-3 m").map(|p| p.value), Ok(1.0));
        assert_eq!(parse("5 m").map(|p| p.value), Ok(5000.0));
        assert_eq!(parse("-2.5 deg").map(|p| p.value), Ok(-2.5));
    }

    #[test]
    fn errors_say_what_to_write() {
        let e = parse("2 mmm").expect_err("unknown unit");
        assert!(e.contains("did you mean `mm`"), "{e}");
        let e = parse("mm").expect_err("no number");
        assert!(e.contains("does not start with a number"), "{e}");
        let e = parse("2").expect_err("no unit");
        assert!(e.contains("has no unit"), "{e}");
    }

    #[test]
    fn deserialize_checks_dimension() {
        let ok: T = serde_yaml::from_str("{l: 9.5 mm, q: 2 %, t: 0.5 N·m}").expect("valid");
        assert_eq!(ok.l.mm(), 9.5);
        assert_eq!(ok.q, AxisQuantity::Percent(2.0));
        assert_eq!(ok.t.nmm(), 500.0);
        let e = serde_yaml::from_str::<T>("{l: 9.5 s, q: 2 %, t: 1 Nmm}").expect_err("time");
        assert!(e.to_string().contains("is a duration, but a length"), "{e}");
        let e = serde_yaml::from_str::<T>("{l: 9.5, q: 2 %, t: 1 Nmm}").expect_err("bare");
        assert!(e.to_string().contains("`9.5 mm`"), "{e}");
    }

    #[test]
    fn display_round_trips() {
        for text in ["0.084 mm", "180 s", "0.5 mm/s", "2 %", "1 deg"] {
            let q: AxisQuantity = match serde_yaml::from_str(text) {
                Ok(q) => q,
                Err(_) => continue,
            };
            let again: AxisQuantity = serde_yaml::from_str(&q.to_string()).expect("round trip");
            assert_eq!(q, again);
        }
        assert_eq!(fmt_value(0.1 + 0.2), "0.3");
    }
}
