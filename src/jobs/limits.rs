//! The limits a scene must fit before it is queued, checked before any work starts.
//!
//! Particles and springs are counted from the scene without building anything; only a scene
//! within those limits is compiled (which allocates its particles), and its steps, its output
//! and the work and memory of every stage it switches on (see [`Cost`]) are then checked against
//! the compiled plan. Every refusal names the field to change. Self-collision, whose pairs can
//! grow as the run goes, is also given a hard cap on the pairs it holds: what the job's memory
//! allowance leaves after everything else, shared by the main run and a companion beside it. A
//! run that meets more ends as failed, never by running out of memory.

use crate::scene::{Body, Compiled, FieldError, Scene};

#[cfg(test)]
use super::cost::{BYTES_PER_COLLIDER_TRIANGLE, BYTES_PER_COLLIDER_VERTEX};
use super::cost::{BYTES_PER_PAIR, Cost, companion_steps, recorded, size_field};
use super::record::Plan;

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
    /// Work of one run, in element-steps (see [`Cost`]), companions included.
    pub max_work: u64,
    /// Bytes one run may hold at once (its share of the memory budget).
    pub max_memory: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_particles: 100_000,
            max_springs: 1_000_000,
            max_steps: 1_000_000,
            max_output_values: 20_000_000,
            max_work: 200_000_000_000,
            max_memory: 2 << 30,
        }
    }
}

/// A scene that fits the limits: compiled, with its plan and its cost.
#[derive(Debug)]
pub struct Admitted {
    /// The scene compiled, with its self-collision cap set.
    pub compiled: Compiled,
    /// Its size.
    pub plan: Plan,
    /// Its work and memory, stage by stage.
    pub cost: Cost,
}

impl Limits {
    /// Checks `scene` against the limits and compiles it; every limit exceeded is listed.
    pub fn admit(&self, scene: &Scene) -> Result<Admitted, Vec<FieldError>> {
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

        let mut compiled = scene.compile();
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
        let (frames, values) = recorded(&compiled, &plan);
        // Each frame holds its time besides its fields, so the frames are counted on their own.
        if values > self.max_output_values || frames > self.max_output_values {
            let (pointer, remedy) = if frames > 1 {
                ("/output/fps", "record fewer frames (a lower fps) or fewer fields")
            } else {
                ("/output/fields", "record fewer fields")
            };
            errors.push(FieldError::new(
                pointer,
                format!(
                    "the result would hold {values} values ({frames} frames × particles × fields); this \
                     server allows at most {} (--max-output-values): {remedy}",
                    self.max_output_values
                ),
            ));
        }
        if !errors.is_empty() {
            return Err(errors);
        }

        let cost = Cost::of(scene, &compiled, &plan);
        let work = cost.work();
        if work > self.max_work {
            let stage = cost.largest(|s| s.work).expect("a run has a stage");
            errors.push(FieldError::new(
                stage.pointer.clone(),
                format!(
                    "the run needs {work} element-steps of work ({} of them for {}); this server allows \
                     at most {} (--max-work)",
                    stage.work, stage.stage, self.max_work
                ),
            ));
        }
        let memory = cost.memory();
        if memory > self.max_memory {
            let stage = cost.largest(|s| s.memory).expect("a run has a stage");
            errors.push(FieldError::new(
                stage.pointer.clone(),
                format!(
                    "the run needs about {} of memory ({} of it for {}); a run here may hold {} \
                     (--memory-budget shared by the runs at once)",
                    bytes(memory),
                    bytes(stage.memory),
                    stage.stage,
                    bytes(self.max_memory)
                ),
            ));
        }
        if !errors.is_empty() {
            return Err(errors);
        }

        // What the allowance leaves for pairs beyond those counted, shared by the runs at once.
        let spare = (self.max_memory - memory) / BYTES_PER_PAIR / cost.concurrent_runs();
        let per_run = cost.pairs.max(plan.particles).saturating_add(spare);
        compiled.config.max_self_collision_pairs = usize::try_from(per_run).unwrap_or(usize::MAX);
        Ok(Admitted { compiled, plan, cost })
    }
}

/// A byte count for people: `512 MiB`, `3.2 GiB`.
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut value = n as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 { format!("{n} bytes") } else { format!("{value:.1} {}", UNITS[unit]) }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(json: &str) -> Scene {
        Scene::from_json(json.as_bytes()).unwrap()
    }

    #[test]
    fn a_small_scene_is_admitted_with_its_plan() {
        // This chain's stability bound is 0.0141 s: 0.005 s keeps it at twice the step.
        let plan = Limits::default()
            .admit(&scene(r#"{"duration": 1, "dt": 0.005, "bodies": [{"type": "chain", "count": 5}]}"#))
            .unwrap()
            .plan;
        assert_eq!((plan.particles, plan.springs, plan.steps), (5, 4, 200));
        // The default Richardson estimate adds a companion run of 100 steps.
        assert_eq!((plan.companion_steps, plan.work()), (100, 1500));
        let json =
            r#"{"duration": 1, "dt": 0.005, "bodies": [{"type": "chain", "count": 5}], "error_estimate": "#;
        let work = |method: &str| {
            Limits::default().admit(&scene(&format!("{json}\"{method}\"}}"))).unwrap().plan.work()
        };
        // richardson3's companion at four times the step would pass the bound: it takes half and a
        // quarter of the step instead, 400 + 800 steps.
        assert_eq!((work("none"), work("richardson3")), (1000, 7000));
        // At 0.01 s, twice the step passes the bound: the companion runs at half the step.
        let near_the_bound = r#"{"duration": 1, "dt": 0.01, "bodies": [{"type": "chain", "count": 5}]}"#;
        let plan = Limits::default().admit(&scene(near_the_bound)).unwrap().plan;
        assert_eq!((plan.companion_steps, plan.work()), (200, 1500));
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
        assert_eq!(errors[0].pointer, "/output/fps");
    }

    /// The 629-byte scene of the issue: a thickness of 10 m puts all 90,000 particles of a 1 m
    /// cloth in one cell, every pair of them a candidate.
    const THICK_CLOTH: &str = r#"{"duration":0.01,"dt":0.005,"integrator":"symplectic_euler","error_estimate":"none",
        "self_collision":{"thickness":10},"bodies":[{"type":"cloth","resolution":[300,300],"size":[1,1]}],
        "output":{"frames":"final"}}"#;

    fn pointers(errors: &[FieldError]) -> Vec<&str> {
        errors.iter().map(|e| e.pointer.as_str()).collect()
    }

    #[test]
    fn a_thickness_that_makes_every_pair_a_candidate_is_refused_at_the_thickness() {
        let errors = Limits::default().admit(&scene(THICK_CLOTH)).unwrap_err();
        assert_eq!(pointers(&errors), ["/self_collision/thickness"]);
        // 90,000 · 89,999 / 2 pairs of 8 bytes.
        assert!(errors[0].detail.contains("30.2 GiB of it for self_collision"), "{}", errors[0].detail);
    }

    #[test]
    fn a_thin_thickness_costs_its_pairs_and_a_tight_budget_refuses_it() {
        let thin = THICK_CLOTH.replace(r#""thickness":10"#, r#""thickness":0.02"#);
        let admitted = Limits::default().admit(&scene(&thin)).unwrap();
        // Cells of 0.04 m over a spacing of 1/299 m: about 12 × 12 particles a cell, each
        // meeting its own cell's and four neighbouring cells' in the plane.
        let pairs = admitted.cost.pairs;
        assert!((40_000_000..80_000_000).contains(&pairs), "{pairs}");
        let stage = admitted.cost.stages.iter().find(|s| s.stage == "self_collision").unwrap();
        assert_eq!(stage.work, (90_000 + pairs) * 2);
        assert!(stage.memory > pairs * 8 && stage.memory < pairs * 8 + 90_000 * 200, "{}", stage.memory);
        // The cap: the pairs counted and all the allowance leaves.
        let spare = (Limits::default().max_memory - admitted.cost.memory()) / 8;
        assert_eq!(admitted.compiled.config.max_self_collision_pairs as u64, pairs + spare);

        let tight = Limits { max_memory: 256 << 20, ..Limits::default() };
        assert_eq!(pointers(&tight.admit(&scene(&thin)).unwrap_err()), ["/self_collision/thickness"]);
    }

    #[test]
    fn ten_thousand_colliders_cost_their_tests_and_are_refused_at_the_colliders() {
        let spheres: Vec<String> = (0..10_000)
            .map(|i| format!(r#"{{"type":"sphere","center":[{},-5,0],"radius":0.01}}"#, i as f64 * 0.001))
            .collect();
        let json = format!(
            r#"{{"duration":0.1,"dt":0.001,"error_estimate":"none","bodies":[{{"type":"cloth","resolution":[32,32]}}],
                "colliders":[{}]}}"#,
            spheres.join(",")
        );
        let admitted = Limits::default().admit(&scene(&json)).unwrap();
        let colliders = admitted.cost.stages.iter().find(|s| s.stage == "colliders").unwrap();
        assert_eq!(colliders.work, 1024 * 10_000 * 100);
        assert_eq!(colliders.pointer, "/colliders");
        let limits = Limits { max_work: 1_000_000_000, ..Limits::default() };
        let errors = limits.admit(&scene(&json)).unwrap_err();
        assert_eq!(pointers(&errors), ["/colliders"]);
        assert!(errors[0].detail.contains("1024000000 of them for colliders"), "{}", errors[0].detail);
    }

    #[test]
    fn a_mesh_collider_costs_its_walks_and_its_hierarchy_and_is_refused_at_its_triangles() {
        // A strip of 1,000 triangles: a hierarchy 10 levels deep.
        let vertices: Vec<String> = (0..1002).map(|i| format!("{},0,{}", i / 2, i % 2)).collect();
        let triangles: Vec<String> = (0..1000).map(|t| format!("{},{},{}", t, t + 1, t + 2)).collect();
        let json = format!(
            r#"{{"duration":0.1,"dt":0.001,"error_estimate":"none","bodies":[{{"type":"cloth","resolution":[4,4]}}],
                "colliders":[{{"type":"plane"}},{{"type":"mesh","vertices":[{}],"triangles":[{}]}}]}}"#,
            vertices.join(","),
            triangles.join(",")
        );
        let admitted = Limits::default().admit(&scene(&json)).unwrap();
        let mesh = admitted.cost.stages.iter().find(|s| s.stage == "mesh").unwrap();
        assert_eq!(mesh.pointer, "/colliders/1/triangles");
        // Two walks of ⌊log₂ 1000⌋ + 1 = 10 levels and a leaf of 4, per particle and step.
        assert_eq!(mesh.work, 16 * 2 * (10 + 4) * 100);
        assert_eq!(mesh.memory, 1000 * BYTES_PER_COLLIDER_TRIANGLE + 1002 * BYTES_PER_COLLIDER_VERTEX);
        let tight = Limits { max_memory: admitted.cost.memory() - 1, ..Limits::default() };
        let errors = tight.admit(&scene(&json)).unwrap_err();
        assert_eq!(pointers(&errors), ["/colliders/1/triangles"]);
    }

    #[test]
    fn runaway_sizes_are_refused_at_the_field_that_sets_them() {
        for (json, pointer) in [
            (r#"{"duration": 1, "output": {"fps": 1e9}, "bodies": [{"type": "chain"}]}"#, "/output/fps"),
            (
                r#"{"duration": 1, "output": {"fps": 1e30, "fields": []}, "bodies": [{"type": "chain"}]}"#,
                "/output/fps",
            ),
            (r#"{"duration": 1e9, "bodies": [{"type": "chain"}]}"#, "/duration"),
            (r#"{"duration": 1, "dt": 1e-12, "bodies": [{"type": "chain"}]}"#, "/dt"),
            (
                r#"{"duration": 1, "bodies": [{"type": "cloth", "resolution": [100000, 100000]}]}"#,
                "/bodies/0/resolution",
            ),
        ] {
            let errors = Limits::default().admit(&scene(json)).unwrap_err();
            assert_eq!(errors[0].pointer, pointer, "{json}: {errors:?}");
        }
    }

    /// A drape tester's coefficient is measured once, within the row crossings it allows itself:
    /// 4096 per triangle of its 6·15² (or 2²⁰ rows' worth at least), the rows, and three edges
    /// per triangle; a disk's particles and springs are counted exactly, its springs as listed.
    #[test]
    fn a_drape_tester_costs_its_measurement_and_a_disk_its_exact_counts() {
        let json = r#"{"duration": 1, "dt": 0.01, "error_estimate": "none",
            "bodies": [{"type": "cloth", "shape": "disk", "diameter": 0.3, "resolution": [31, 31]}],
            "colliders": [{"type": "cylinder", "center": [0, 0.4, 0], "radius": 0.09, "height": 0.2}]}"#;
        let admitted = Limits::default().admit(&scene(json)).unwrap();
        assert_eq!((admitted.plan.particles, admitted.plan.springs), (721, 18 * 225));
        let stage = admitted.cost.stages.iter().find(|s| s.stage == "drape_coefficient").unwrap();
        assert_eq!(stage.pointer, "/bodies/0/shape");
        let triangles = 6 * 225;
        assert_eq!(stage.work, (triangles * 4096u64).max(1 << 20) + (1 << 20) + 3 * triangles);
        let rectangle = json.replace(
            r#""shape": "disk", "diameter": 0.3, "resolution": [31, 31]"#,
            r#""resolution": [27, 27]"#,
        );
        let rectangle = Limits::default().admit(&scene(&rectangle)).unwrap();
        assert!(rectangle.cost.stages.iter().all(|s| s.stage != "drape_coefficient"));
        let huge = json.replace("[31, 31]", "[100000, 100000]");
        let errors = Limits::default().admit(&scene(&huge)).unwrap_err();
        assert_eq!(errors[0].pointer, "/bodies/0/resolution");
    }

    #[test]
    fn memory_counts_every_stage_and_a_companion_beside_the_run() {
        let json = r#"{"duration": 1, "dt": 0.01, "bodies": [{"type": "cloth", "resolution": [10, 10]}],
                       "colliders": [{"type": "plane"}], "self_collision": {"thickness": 0.001}}"#;
        let admitted = Limits::default().admit(&scene(json)).unwrap();
        let names: Vec<&str> = admitted.cost.stages.iter().map(|s| s.stage).collect();
        assert_eq!(names, ["bodies", "colliders", "self_collision", "frames", "error_estimate"]);
        let memory = |name: &str| admitted.cost.stages.iter().find(|s| s.stage == name).unwrap().memory;
        // The companion holds a simulation of its own: everything but the model and the frames.
        assert!(memory("error_estimate") < memory("bodies") + memory("colliders") + memory("self_collision"));
        assert!(memory("error_estimate") > memory("colliders") + memory("self_collision"));
        // Two runs hold pairs at once, so each gets half the spare room.
        let spare = (Limits::default().max_memory - admitted.cost.memory()) / 8 / 2;
        assert_eq!(admitted.compiled.config.max_self_collision_pairs as u64, 100 + spare);
    }
}
