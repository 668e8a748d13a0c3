//! What a run produces: the mesh, the recorded frames, and the statistics of the run.

use super::{ErrorEstimate, RecordedCollider};
use crate::scene::{BodyInfo, DtSource, FrameSelection, Precision};
use crate::solver::{Energy, IntegratorKind, LinearSolveStats};

/// The outcome of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Ran to the end (or to rest).
    Succeeded,
    /// Stopped because the state blew up.
    Diverged,
    /// Stopped because the caller asked.
    Cancelled,
    /// Stopped because a stage met more than the run may hold (`Stats::failure` says what).
    Failed,
}

impl Status {
    /// The name the contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Succeeded => "succeeded",
            Self::Diverged => "diverged",
            Self::Cancelled => "cancelled",
            Self::Failed => "failed",
        }
    }
}

/// Per-frame values of one field, flat over frames then particles, in the run's precision.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// Single precision.
    F32(Vec<f32>),
    /// Double precision.
    F64(Vec<f64>),
}

impl Samples {
    /// The number of scalars.
    pub fn len(&self) -> usize {
        match self {
            Self::F32(v) => v.len(),
            Self::F64(v) => v.len(),
        }
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values widened to `f64` (exact).
    pub fn to_f64(&self) -> Vec<f64> {
        match self {
            Self::F32(v) => v.iter().map(|&x| f64::from(x)).collect(),
            Self::F64(v) => v.clone(),
        }
    }
}

impl From<Vec<f32>> for Samples {
    fn from(v: Vec<f32>) -> Self {
        Self::F32(v)
    }
}

impl From<Vec<f64>> for Samples {
    fn from(v: Vec<f64>) -> Self {
        Self::F64(v)
    }
}

/// The recorded frames: times and, for each field asked for, its values.
#[derive(Clone, Debug, PartialEq)]
pub struct Frames {
    /// Simulated time of each frame, in seconds.
    pub times: Vec<f64>,
    /// Positions, 3 per particle per frame.
    pub positions: Option<Samples>,
    /// Velocities, 3 per particle per frame.
    pub velocities: Option<Samples>,
    /// Unit normals, 3 per particle per frame.
    pub normals: Option<Samples>,
    /// Energies, one per frame.
    pub energy: Option<Vec<Energy>>,
    /// Spring strains, one per spring per frame.
    pub strain: Option<Vec<f64>>,
}

impl Frames {
    /// The number of frames.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Whether no frame was recorded.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }
}

/// Where and why a run diverged.
#[derive(Clone, Debug, PartialEq)]
pub struct Diverged {
    /// The step after which the state was bad.
    pub step: u64,
    /// Simulated time then, in seconds.
    pub t: f64,
    /// What went wrong.
    pub reason: String,
    /// A step that the stability bound says would hold, in seconds.
    pub suggested_dt: Option<f64>,
}

/// How a run went.
#[derive(Clone, Debug, PartialEq)]
pub struct Stats {
    /// The outcome.
    pub status: Status,
    /// Wall-clock time of the run, in seconds.
    pub wall_time_s: f64,
    /// Steps taken.
    pub steps: u64,
    /// The step, in seconds.
    pub dt: f64,
    /// Where the step came from.
    pub dt_source: DtSource,
    /// The integrator.
    pub integrator: IntegratorKind,
    /// The precision.
    pub precision: Precision,
    /// The stages each step ran, and the per-frame ones the output asked for.
    pub stages: Vec<&'static str>,
    /// Energies at the end (absent unless the run succeeded).
    pub energy: Option<Energy>,
    /// Largest spring strain at the end (absent unless the run succeeded).
    pub max_strain: Option<f64>,
    /// The scene's stability bound for this integrator, in seconds.
    pub stable_dt: Option<f64>,
    /// Present when the run diverged.
    pub diverged: Option<Diverged>,
    /// Why the run failed, when it did.
    pub failure: Option<String>,
    /// The time at which the run was found at rest (every particle slower than `stop_at_rest`,
    /// by velocity and by displacement, and balanced; see [`run`](crate::run)), if it was.
    pub stopped_at_rest: Option<f64>,
    /// Implicit Euler's conjugate-gradient figures.
    pub linear_solver: Option<LinearSolveStats>,
    /// The run's estimate of its own error, when asked for and the run finished.
    pub error: Option<ErrorEstimate>,
    /// The drape coefficient of the final state, when the scene is a drape tester
    /// ([`DrapeTester`](crate::scene::DrapeTester)) and the run succeeded.
    pub drape_coefficient: Option<f64>,
}

/// Everything a run produced.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// Particle count.
    pub particles: usize,
    /// Spring count.
    pub springs: usize,
    /// Surface triangles.
    pub triangles: Vec<[u32; 3]>,
    /// The bodies' names and particle ranges.
    pub bodies: Vec<BodyInfo>,
    /// Which frames were asked for.
    pub selection: FrameSelection,
    /// The recorded frames.
    pub frames: Frames,
    /// The scene's colliders, in scene order (empty when it has none).
    pub colliders: Vec<RecordedCollider>,
    /// Whether the last recorded frame is the final state of a finished run.
    pub has_final: bool,
    /// How the run went.
    pub stats: Stats,
}
