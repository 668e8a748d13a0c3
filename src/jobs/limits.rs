//! The size limits a scene must fit before it is queued, checked before any work starts.
//!
//! Particles and springs are counted from the scene without building anything; only a scene
//! within those limits is compiled (which allocates its particles), and its steps and output
//! size are then checked against the compiled plan. Every refusal names the field to change.

use crate::scene::{Body, Compiled, ErrorEstimateName, Field, FieldError, FrameSelection, Scene};

use super::Plan;

/// The largest run this server accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Particles over all bodies.
    pub max_particles: u64,
    /// Springs over all bodies.
    pub max_springs: u64,
    /// Steps of one run.
    pub max_steps: u64,
    /// Recorded values: frames × (particles × fields + per-frame values).
    pub max_output_values: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_particles: 100_000,
            max_springs: 1_000_000,
            max_steps: 1_000_000,
            max_output_values: 20_000_000,
        }
    }
}

impl Limits {
    /// Checks `scene` against the limits and compiles it; every limit exceeded is listed.
    pub fn admit(&self, scene: &Scene) -> Result<(Compiled, Plan), Vec<FieldError>> {
        let mut errors = Vec::new();
        let particles = scene.bodies.iter().map(Body::particle_count).fold(0, u64::saturating_add);
        if particles > self.max_particles {
            let at = first_over(&scene.bodies, self.max_particles, Body::particle_count);
            errors.push(FieldError::new(
                format!("/bodies/{at}{}", size_field(&scene.bodies[at])),
                format!(
                    "the scene has {particles} particles; this server accepts at most {} (--max-particles)",
                    self.max_particles
                ),
            ));
        }
        let springs = scene.bodies.iter().map(Body::spring_count).fold(0, u64::saturating_add);
        if springs > self.max_springs {
            let at = first_over(&scene.bodies, self.max_springs, Body::spring_count);
            errors.push(FieldError::new(
                format!("/bodies/{at}{}", size_field(&scene.bodies[at])),
                format!(
                    "the scene has up to {springs} springs; this server accepts at most {} (--max-springs)",
                    self.max_springs
                ),
            ));
        }
        if !errors.is_empty() {
            return Err(errors);
        }

        let compiled = scene.compile();
        let plan = Plan {
            particles: compiled.model.particle_count() as u64,
            springs: compiled.model.springs.len() as u64,
            steps: compiled.steps,
            companion_steps: companion_steps(&compiled),
            dt: compiled.config.dt,
            duration: compiled.duration,
        };
        if plan.steps > self.max_steps {
            let (pointer, how) = if scene.dt.is_some() {
                ("/dt", "duration / dt")
            } else {
                ("/duration", "duration / the automatic step")
            };
            errors.push(FieldError::new(
                pointer,
                format!(
                    "the run needs {} steps ({how}); this server allows at most {} (--max-steps)",
                    plan.steps, self.max_steps
                ),
            ));
        }
        let values = output_values(&compiled, &plan);
        if values > self.max_output_values {
            errors.push(FieldError::new(
                "/output",
                format!(
                    "the result would hold {values} values (frames × particles × fields); this server \
                     allows at most {} (--max-output-values): record fewer frames or fields",
                    self.max_output_values
                ),
            ));
        }
        if errors.is_empty() { Ok((compiled, plan)) } else { Err(errors) }
    }
}

/// Steps of the error estimate's companions: at twice the step, and for `richardson3` also at
/// four times the step.
fn companion_steps(compiled: &Compiled) -> u64 {
    match compiled.error_estimate {
        ErrorEstimateName::None => 0,
        ErrorEstimateName::Richardson => compiled.steps / 2,
        ErrorEstimateName::Richardson3 => compiled.steps / 2 + compiled.steps / 4,
    }
}

/// The index of the body at which the running total first exceeds `limit`.
fn first_over(bodies: &[Body], limit: u64, count: fn(&Body) -> u64) -> usize {
    let mut total = 0u64;
    bodies
        .iter()
        .position(|b| {
            total = total.saturating_add(count(b));
            total > limit
        })
        .unwrap_or(bodies.len().saturating_sub(1))
}

/// The field that sets a body's size.
fn size_field(body: &Body) -> &'static str {
    match body {
        Body::Cloth(_) | Body::Lattice(_) => "/resolution",
        Body::Chain(_) => "/count",
        Body::Mesh(_) => "/vertices",
    }
}

/// An upper bound on the values a run records.
fn output_values(compiled: &Compiled, plan: &Plan) -> u64 {
    let output = &compiled.output;
    let frames = match output.frames {
        FrameSelection::All => ((plan.duration * output.fps).floor() as u64).saturating_add(2),
        FrameSelection::Final => 1,
        FrameSelection::None => 0,
    };
    let per_frame = output
        .fields
        .iter()
        .map(|field| match field {
            Field::Positions | Field::Velocities | Field::Normals => plan.particles.saturating_mul(3),
            Field::Energy => 3,
            Field::Strain => plan.springs,
        })
        .fold(0, u64::saturating_add);
    frames.saturating_mul(per_frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(json: &str) -> Scene {
        Scene::from_json(json.as_bytes()).unwrap()
    }

    #[test]
    fn a_small_scene_is_admitted_with_its_plan() {
        let (_, plan) = Limits::default()
            .admit(&scene(r#"{"duration": 1, "dt": 0.01, "bodies": [{"type": "chain", "count": 5}]}"#))
            .unwrap();
        assert_eq!((plan.particles, plan.springs, plan.steps), (5, 4, 100));
        // The default Richardson estimate adds a companion run of 50 steps.
        assert_eq!((plan.companion_steps, plan.work()), (50, 750));
        let json =
            r#"{"duration": 1, "dt": 0.01, "bodies": [{"type": "chain", "count": 5}], "error_estimate": "#;
        let work = |method: &str| {
            Limits::default().admit(&scene(&format!("{json}\"{method}\"}}"))).unwrap().1.work()
        };
        assert_eq!((work("none"), work("richardson3")), (500, 875));
    }

    #[test]
    fn too_many_particles_points_at_the_body_that_crosses_the_limit() {
        let limits = Limits { max_particles: 30, ..Limits::default() };
        let errors = limits
            .admit(&scene(
                r#"{"duration": 1, "bodies": [{"type": "chain", "count": 20},
                    {"type": "cloth", "resolution": [4, 4]}]}"#,
            ))
            .unwrap_err();
        assert_eq!(errors[0].pointer, "/bodies/1/resolution");
        assert!(errors[0].detail.contains("36 particles"), "{}", errors[0].detail);
    }

    #[test]
    fn too_many_steps_points_at_dt() {
        let limits = Limits { max_steps: 99, ..Limits::default() };
        let errors = limits
            .admit(&scene(r#"{"duration": 1, "dt": 0.01, "bodies": [{"type": "chain"}]}"#))
            .unwrap_err();
        assert_eq!(errors.len(), 1);
        assert_eq!(errors[0].pointer, "/dt");
        assert!(errors[0].detail.contains("100 steps"));
    }

    #[test]
    fn output_size_counts_frames_particles_and_fields() {
        // 1 s at 10 fps: at most 12 frames; 4 particles × 3 × 2 fields = 24 values a frame.
        let json = r#"{"duration": 1, "dt": 0.01, "bodies": [{"type": "chain", "count": 4}],
                       "output": {"fps": 10, "fields": ["positions", "velocities"]}}"#;
        assert!(Limits { max_output_values: 288, ..Limits::default() }.admit(&scene(json)).is_ok());
        let errors = Limits { max_output_values: 287, ..Limits::default() }.admit(&scene(json)).unwrap_err();
        assert_eq!(errors[0].pointer, "/output");
    }
}
