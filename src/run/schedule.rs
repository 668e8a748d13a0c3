//! Which steps a run records a frame at.
//!
//! `frames: all` records at `t = k / fps` for `k = 0, 1, ...` up to `duration`, each at the
//! nearest step, and always at the last step, so the last frame is at exactly `duration`.
//! `final` records the last step only; `none` records nothing.

use crate::scene::{Compiled, FrameSelection};

pub(super) struct FrameSchedule {
    /// Steps to record at, increasing, without repeats.
    pub steps: Vec<u64>,
    duration: f64,
    total: u64,
}

impl FrameSchedule {
    pub fn new(compiled: &Compiled) -> Self {
        let (total, dt) = (compiled.steps, compiled.config.dt);
        let steps = match compiled.output.frames {
            FrameSelection::None => Vec::new(),
            FrameSelection::Final => vec![total],
            FrameSelection::All => {
                let interval = 1.0 / compiled.output.fps;
                let count = (compiled.duration / interval * (1.0 + 1e-12)).floor() as u64;
                // Frames closer than a step fall on the same step; kept once as they come, so
                // that the list never outgrows the steps.
                let mut steps: Vec<u64> = Vec::new();
                for step in (0..=count).map(|k| ((k as f64 * interval / dt).round() as u64).min(total)) {
                    if steps.last() != Some(&step) {
                        steps.push(step);
                    }
                }
                if steps.last() != Some(&total) {
                    steps.push(total);
                }
                steps
            }
        };
        Self { steps, duration: compiled.duration, total }
    }

    /// Simulated time at a step: exact at the last step.
    pub fn time_of(&self, step: u64) -> f64 {
        if step == self.total { self.duration } else { self.duration * step as f64 / self.total as f64 }
    }
}
