//! The named fabrics a `material` may give instead of its values (`"material": "denim"`), with
//! where each value comes from.
//!
//! `cotton`, `denim` and `polyester` are fabrics of the database of Wang, O'Brien and Ramamoorthi,
//! "Data-driven elastic models for cloth: modeling and measurement" (SIGGRAPH 2011), as ARCSim
//! distributes it: its areal density as measured; `stretch` the geometric mean of the two thread
//! directions' held-uniaxial stiffnesses and `shear` half the shear entry (that database's energy
//! has `k₃ ε₁₂²` where this one has `½ G γ²`, `γ = 2ε₁₂`), each the median over its strain
//! samples; `bending` the median of its bending samples (N·m, over three directions and five
//! curvatures). `silk` and `wool` are not from a measurement: `docs/materials.md` says how each
//! value was chosen.

use super::fabrics::{DEFAULT_DAMPING_TIME, FabricSpec};

/// A named fabric.
const fn preset(density: f64, stretch: f64, shear: f64, bending: f64) -> FabricSpec {
    FabricSpec { density, stretch, shear, bending, damping: DEFAULT_DAMPING_TIME }
}

/// Every preset by name, in the order the documentation lists them.
pub const PRESETS: [(&str, FabricSpec); 5] = [
    // Wang et al.'s "royal-target": trousers twill, 65 % cotton, 35 % polyester.
    ("cotton", preset(0.220, 2127.0, 20.2, 1.673e-4)),
    // Wang et al.'s "11oz-black-denim": jeans, 99 % cotton, 1 % spandex.
    ("denim", preset(0.324, 488.0, 34.7, 6.42e-5)),
    // Wang et al.'s "white-dots-on-blk": tablecloth, 100 % polyester.
    ("polyester", preset(0.128, 2124.0, 15.5, 3.06e-5)),
    // A 14 momme crêpe de chine's weight; the membrane of the measured polyester, also a
    // filament weave; a bending rigidity chosen for a bending length of 2 cm.
    ("silk", preset(0.061, 2124.0, 15.5, 4.8e-6)),
    // Chosen, not measured: a suiting weight, the measured cotton's membrane, a bending length
    // of 2.7 cm.
    ("wool", preset(0.250, 2127.0, 20.2, 4.8e-5)),
];

/// The preset called `name`.
pub fn find(name: &str) -> Option<FabricSpec> {
    PRESETS.iter().find(|(known, _)| *known == name).map(|&(_, spec)| spec)
}

/// The presets' names, as a message lists them: "`cotton`, `denim`, … or `wool`".
pub fn names() -> String {
    let quoted: Vec<String> = PRESETS.iter().map(|(name, _)| format!("`{name}`")).collect();
    let (last, rest) = quoted.split_last().expect("there are presets");
    format!("{} or {last}", rest.join(", "))
}
