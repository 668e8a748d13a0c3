//! A body's `material`: a fabric in physical units (`docs/materials.md` has the units and how
//! they become a body's springs, bending elements and masses).

use serde::Deserialize;

use crate::solver::Fabric;

/// A fabric in physical units, as the JSON spells it.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
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
    #[serde(default = "default_damping_time")]
    pub damping: f64,
}

/// The damping time constant a material has unless it says otherwise, in seconds. It damps a
/// mode of angular frequency `ω` at the rate `½ τ ω²`: the membrane's fast stretching modes
/// within a few of their periods, a drape's slow swings hardly at all. Larger values also shorten
/// the step the explicit integrators can take, which the damping of the fastest mode bounds.
pub const DEFAULT_DAMPING_TIME: f64 = 1e-4;

fn default_damping_time() -> f64 {
    DEFAULT_DAMPING_TIME
}

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
