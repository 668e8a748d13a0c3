//! Strain limiting (Provot, 1995): no spring may end a step longer than `(1 + limit)` times its
//! rest length.
//!
//! Stiff cloth needs stiff springs, and stiff springs need tiny explicit steps. Provot instead
//! lets the springs be soft and, after each step, shortens every spring that is too long by moving
//! its ends towards each other, shared by inverse mass, so a pinned end never moves. Shortening one
//! spring can stretch its neighbours, so the pass sweeps (Gauss-Seidel, alternating forwards and
//! backwards) until a whole sweep finds no spring more than [`TOLERANCE`] (relative) beyond its
//! limit, or [`MAX_SWEEPS`] is reached. Within a step the excess is small and a few sweeps do; a
//! chain pulled far beyond its limit needs sweeps growing with the square of its length, since the
//! excess can only leave through free ends.
//! A particle moved by `Δx` gets `Δx / h` added to its velocity, the velocity that would have
//! brought it there, so that the state stays consistent.
//!
//! With colliders, shortening springs can pull particles into a collider and pushing them out
//! again can stretch springs. So before each sweep the particles are projected out of the colliders
//! (positions only: the contact stage that follows gives them their contact response), and the
//! sweeps go on until both hold. Those projections are not turned into velocity.

#![allow(clippy::neg_cmp_op_on_partial_ord, reason = "written so that a NaN fails each test")]

use super::contacts::Contacts;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::model::Spring;
use crate::solver::state::State;

/// The relative excess over the limit a converged sweep tolerates.
pub const TOLERANCE: f64 = 1e-9;

/// The most sweeps one pass makes.
pub const MAX_SWEEPS: usize = 10_000;

/// The strain-limiting stage and its scratch.
#[derive(Clone, Debug)]
pub(crate) struct StrainLimit<T> {
    /// `1 + limit`.
    stretch: T,
    /// How far the springs moved each particle in this pass.
    shift: Vectors<T>,
    /// Sweeps of the last pass.
    last_sweeps: usize,
}

impl<T: Real> StrainLimit<T> {
    pub fn new(limit: f64, particles: usize) -> Self {
        Self { stretch: T::from_f64(1.0 + limit), shift: Vectors::zeros(particles), last_sweeps: 0 }
    }

    /// Sweeps of the last pass (zero when no spring was too long).
    #[cfg(test)]
    pub fn last_sweeps(&self) -> usize {
        self.last_sweeps
    }

    /// Shortens the springs that are too long, keeping particles out of the colliders if any;
    /// returns whether any particle moved.
    pub fn apply(
        &mut self,
        state: &mut State<T>,
        springs: &[Spring<T>],
        inverse_masses: &[T],
        contacts: Option<&Contacts<T>>,
        h: T,
    ) -> bool {
        let tolerance = T::from_f64(TOLERANCE);
        let x = &mut state.positions;
        let mut moved = false;
        self.last_sweeps = 0;
        while self.last_sweeps < MAX_SWEEPS {
            if let Some(contacts) = contacts {
                contacts.project_out(x, inverse_masses);
            }
            let mut worst = T::ZERO;
            // Alternating the direction carries corrections both ways along a chain of springs.
            let forward = self.last_sweeps.is_multiple_of(2);
            for k in 0..springs.len() {
                let s = &springs[if forward { k } else { springs.len() - 1 - k }];
                let (i, j) = (s.i as usize, s.j as usize);
                let (wi, wj) = (inverse_masses[i], inverse_masses[j]);
                let w = wi + wj;
                let longest = s.rest_length * self.stretch;
                let d = x.get(j) - x.get(i);
                let length = d.length();
                // A zero-length spring has no strain to limit.
                if !(length > longest) || w == T::ZERO || longest == T::ZERO {
                    continue;
                }
                worst = worst.max((length - longest) / longest);
                if !moved {
                    self.shift.fill(Vec3::ZERO);
                    moved = true;
                }
                // length > longest ≥ 0, so the direction is defined.
                let correction = d * ((length - longest) / (length * w));
                x.add(i, correction * wi);
                x.sub(j, correction * wj);
                self.shift.add(i, correction * wi);
                self.shift.sub(j, correction * wj);
            }
            self.last_sweeps += 1;
            if !(worst > tolerance) {
                break;
            }
        }
        if moved {
            let rate = T::ONE / h;
            for (v, shift) in state.velocities.axes_mut().into_iter().zip(self.shift.axes()) {
                for (v, &shift) in v.iter_mut().zip(shift) {
                    *v += shift * rate;
                }
            }
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::model::SpringKind;

    fn spring(i: u32, j: u32, rest_length: f64) -> Spring<f64> {
        Spring { i, j, rest_length, stiffness: 1.0, damping: 0.0, kind: SpringKind::Structural }
    }

    fn state(x: Vec<Vec3<f64>>) -> State<f64> {
        let velocities = Vectors::zeros(x.len());
        State { positions: x.into_iter().collect(), velocities }
    }

    #[test]
    fn a_single_overlong_spring_is_cut_to_its_limit_sharing_by_inverse_mass() {
        let mut s = state(vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)]);
        let mut limit = StrainLimit::new(0.1, 2);
        // Particle 1 is three times lighter (inverse mass 3): it moves three times as far.
        assert!(limit.apply(&mut s, &[spring(0, 1, 1.0)], &[1.0, 3.0], None, 0.5));
        let excess = 2.0 - 1.1;
        assert!((s.positions.get(0).x - 0.25 * excess).abs() < 1e-12);
        assert!((s.positions.get(1).x - (2.0 - 0.75 * excess)).abs() < 1e-12);
        // The velocity is the displacement over the step.
        assert!((s.velocities.get(1).x + 0.75 * excess / 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_pinned_end_never_moves_and_a_chain_converges_below_the_limit() {
        // A chain of ten links pulled out to twice its length, pinned at the start.
        let n = 11;
        let x = (0..n).map(|i| Vec3::new(2.0 * i as f64, 0.0, 0.1 * (i % 2) as f64)).collect();
        let mut s = state(x);
        let springs: Vec<_> = (0..n as u32 - 1).map(|i| spring(i, i + 1, 1.0)).collect();
        let mut w = vec![1.0; n];
        w[0] = 0.0;
        let mut limit = StrainLimit::new(0.1, n);
        assert!(limit.apply(&mut s, &springs, &w, None, 0.01));
        assert_eq!(s.positions.get(0), Vec3::ZERO);
        let sweeps = limit.last_sweeps();
        assert!(sweeps > 1 && sweeps < MAX_SWEEPS, "{sweeps}");
        for sp in &springs {
            let l = (s.positions.get(sp.j as usize) - s.positions.get(sp.i as usize)).length();
            assert!(l <= 1.1 * (1.0 + 1e-6), "spring {}-{} is {l}", sp.i, sp.j);
        }
        // A second pass finds at most tolerance-sized remainders: one sweep.
        limit.apply(&mut s, &springs, &w, None, 0.01);
        assert_eq!(limit.last_sweeps(), 1);
    }

    #[test]
    fn springs_within_the_limit_are_left_alone() {
        let x = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.05, 0.0, 0.0)];
        let mut s = state(x.clone());
        let mut limit = StrainLimit::new(0.1, 2);
        assert!(!limit.apply(&mut s, &[spring(0, 1, 1.0)], &[1.0, 1.0], None, 0.01));
        assert_eq!(s.positions, x.into_iter().collect());
    }

    /// A soft cloth hanging from two corners, with and without the limit.
    fn hanging(limit: Option<f64>) -> (crate::solver::model::Model, crate::solver::simulation::Config) {
        use crate::solver::bodies::{Cloth, Orientation};
        use crate::solver::integrators::IntegratorKind;
        use crate::solver::model::{Model, SpringParams};
        use crate::solver::simulation::Config;
        let mut model = Model::default();
        let soft = SpringParams { stiffness: 30.0, damping: 0.1 };
        model.add_cloth(&Cloth {
            size: [1.0, 1.0],
            resolution: [12, 12],
            center: glam::DVec3::new(0.0, 1.0, 0.0),
            orientation: Orientation::Vertical,
            mass: 0.5,
            velocity: glam::DVec3::ZERO,
            structural: soft,
            shear: soft,
            bending: soft,
            pins: vec![[0, 0], [11, 0]],
        });
        let config = Config {
            integrator: IntegratorKind::Verlet,
            dt: 2e-3,
            drag: 0.5,
            strain_limit: limit,
            ..Config::default()
        };
        (model, config)
    }

    #[test]
    fn in_a_simulation_no_spring_ends_a_step_beyond_its_limit_and_pins_hold() {
        use crate::solver::simulation::Simulation;
        let (model, config) = hanging(Some(0.1));
        let mut sim = Simulation::<f64>::new(&model, &config);
        assert_eq!(sim.stages(), ["gravity", "drag", "springs", "strain_limit"]);
        let mut worst: f64 = 0.0;
        for _ in 0..1000 {
            sim.step().unwrap();
            worst = worst.max(sim.max_strain());
        }
        assert!(worst <= 0.1 * (1.0 + 1e-6), "strain reached {worst}");
        assert!(worst > 0.099, "the limit was never reached: {worst}");
        for p in [0, 11] {
            assert_eq!(sim.state().positions.get(p).to_dvec3(), model.positions[p]);
        }

        let (model, config) = hanging(None);
        let mut free = Simulation::<f64>::new(&model, &config);
        assert!(!free.stages().contains(&"strain_limit"));
        for _ in 0..1000 {
            free.step().unwrap();
        }
        assert!(free.max_strain() > 0.2, "the soft cloth should stretch further: {}", free.max_strain());
    }
}
