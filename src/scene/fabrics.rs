//! A body's `material`: a fabric in physical units (`docs/materials.md` has the units and how
//! they become a body's springs, bending elements and masses), given by its values, by a
//! preset's name, or by a preset with some values replaced.

use std::fmt;

use serde::Deserialize;
use serde::de::{self, Deserializer, MapAccess, Visitor, value::MapAccessDeserializer};

use super::fabric_presets;
use crate::solver::Fabric;

/// A fabric in physical units. The JSON gives it as an object of its values, as a preset's name
/// (`"denim"`), or as an object naming a `preset` whose values any field beside it replaces
/// (`{"preset": "denim", "damping": 1e-3}`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FabricSpec {
    /// Mass per area, in kg/m² (positive).
    pub density: f64,
    /// Membrane stiffness in uniaxial stretch with the other direction held, in N/m (positive).
    pub stretch: f64,
    /// Membrane shear stiffness, in N/m (positive, below `stretch`).
    pub shear: f64,
    /// Bending rigidity per unit width, in N·m (positive).
    pub bending: f64,
    /// Damping time constant, in seconds: each element's damping is this times its stiffness
    /// (at least 0; default [`DEFAULT_DAMPING_TIME`]).
    pub damping: f64,
}

/// A `material` object as written: a preset and the values that replace its, or all values.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialFields {
    preset: Option<String>,
    density: Option<f64>,
    stretch: Option<f64>,
    shear: Option<f64>,
    bending: Option<f64>,
    damping: Option<f64>,
}

impl MaterialFields {
    /// The fabric: the preset's values, each replaced by the one given beside it, or without a
    /// preset the values given (all but the damping needed).
    fn fabric(self) -> Result<FabricSpec, String> {
        let base = self.preset.as_deref().map(preset).transpose()?;
        let value = |given: Option<f64>, of_base: fn(&FabricSpec) -> f64, name: &str| {
            given
                .or(base.as_ref().map(of_base))
                .ok_or_else(|| format!("missing field `{name}`: give it, or a `preset` to take it from"))
        };
        Ok(FabricSpec {
            density: value(self.density, |f| f.density, "density")?,
            stretch: value(self.stretch, |f| f.stretch, "stretch")?,
            shear: value(self.shear, |f| f.shear, "shear")?,
            bending: value(self.bending, |f| f.bending, "bending")?,
            damping: self.damping.or(base.map(|f| f.damping)).unwrap_or(DEFAULT_DAMPING_TIME),
        })
    }
}

impl<'de> Deserialize<'de> for FabricSpec {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_any(MaterialVisitor)
    }
}

/// Reads a preset's name or an object; the object's fields are read as a struct of their own,
/// so that an unknown or mistyped field is named by its own pointer.
struct MaterialVisitor;

impl<'de> Visitor<'de> for MaterialVisitor {
    type Value = FabricSpec;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "a preset's name ({}) or an object", fabric_presets::names())
    }

    fn visit_str<E: de::Error>(self, name: &str) -> Result<FabricSpec, E> {
        preset(name).map_err(E::custom)
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<FabricSpec, A::Error> {
        let fields = MaterialFields::deserialize(MapAccessDeserializer::new(map))?;
        fields.fabric().map_err(de::Error::custom)
    }
}

fn preset(name: &str) -> Result<FabricSpec, String> {
    fabric_presets::find(name)
        .ok_or_else(|| format!("unknown preset `{name}`: expected {}", fabric_presets::names()))
}

/// The damping time constant a material has unless it says otherwise, in seconds. It damps a
/// mode of angular frequency `ω` at the rate `½ τ ω²`: the membrane's fast stretching modes
/// within a few of their periods, a drape's slow swings hardly at all. Larger values also shorten
/// the step the explicit integrators can take, which the damping of the fastest mode bounds.
pub const DEFAULT_DAMPING_TIME: f64 = 1e-4;

impl FabricSpec {
    /// The solver's fabric.
    pub fn fabric(&self) -> Fabric {
        Fabric {
            density: self.density,
            stretch: self.stretch,
            shear: self.shear,
            bending: self.bending,
            damping_time: self.damping,
        }
    }

    /// The bending length `c = (B / w)^(1/3)` under gravity `g` (m/s²), with `w = ρ g` the
    /// weight per area: the length of a cantilever whose tip chord falls by 41.5°, halved (the
    /// cantilever's λ = w l³ / B is 8 there).
    pub fn bending_length(&self, g: f64) -> f64 {
        (self.bending / (self.density * g)).cbrt()
    }
}
