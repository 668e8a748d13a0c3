//! Friction carried from one step's contacts into the next step's motion, so that static friction
//! holds a particle still instead of letting it creep.
//!
//! Contacts are resolved after the integrator has moved the particles. A particle that friction
//! holds on a slope had, within the step, slid by `h² a_t` along the surface (its tangential
//! acceleration `a_t`, before friction); zeroing its velocity afterwards leaves that slide in
//! place, so it would creep at `h a_t` for as long as it is held. Putting it back would stretch
//! its springs by a displacement the integrator never saw (energy added after the step). Instead,
//! the friction that balanced the particle's steady tangential force, `-h a_t` as a change of
//! velocity, is given to it at the start of the next step, before the integrator moves it: the
//! integrator sees it as the constant force `m (-a_t)` over the step (for implicit Euler exactly),
//! so the springs see it, and a held particle no longer moves. The contact's projection then only
//! corrects the difference between that friction and the step's own, within Coulomb's cone.
//!
//! Only the steady part is carried: the change that stopped a particle arriving with tangential
//! speed is a one-off, and giving it again would push the particle back. For a particle that
//! slides, the carried part is the friction that would balance its tangential force, capped at
//! Coulomb's `μ Δv_n`. A particle not in contact at the end of a step carries nothing.
//!
//! The stage exists only for implicit Euler and only when a collider has friction: three vectors
//! per particle, filled and read once per step. The explicit integrators take steps small enough
//! for their creep, `h a_t`, to be small, and with friction carried the symplectic reference drape
//! of the contact estimate's tests no longer converges as its step halves, so they keep the
//! projection alone (`docs/decisions.md`, "Friction carried into the next step").

use crate::solver::forces::spring_blocks::LANES;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;

/// Each particle's friction carried into the step, as a change of velocity, the velocities before
/// it was given, and the friction this step carries into the next.
#[derive(Clone, Debug)]
pub(super) struct CarriedFriction<T> {
    carried: Vectors<T>,
    before: Vectors<T>,
    next: Vectors<T>,
}

/// One band's share: the friction carried into the step and the velocities before it, and where
/// the friction to carry on is written.
pub(super) struct BandFriction<'a, T> {
    pub carried: [&'a [T]; 3],
    pub before: [&'a [T]; 3],
    pub next: [&'a mut [T]; 3],
}

impl<T: Real> CarriedFriction<T> {
    pub fn new(particles: usize) -> Self {
        Self {
            carried: Vectors::zeros(particles),
            before: Vectors::zeros(particles),
            next: Vectors::zeros(particles),
        }
    }

    /// Gives each particle the friction carried into this step, remembering its velocity before,
    /// and clears what the step will carry on.
    pub fn begin(&mut self, velocities: &mut Vectors<T>) {
        let ([v0, v1, v2], [c0, c1, c2]) = (velocities.axes_mut(), self.carried.axes());
        let ([b0, b1, b2], [n0, n1, n2]) = (self.before.axes_mut(), self.next.axes_mut());
        for (v, c, b, n) in [(v0, c0, b0, n0), (v1, c1, b1, n1), (v2, c2, b2, n2)] {
            for (((v, &c), b), n) in v.iter_mut().zip(c).zip(b.iter_mut()).zip(n.iter_mut()) {
                *b = *v;
                *v += c;
                *n = T::ZERO;
            }
        }
    }

    /// The carried friction and the velocities before it, for the whole state, and the arrays the
    /// step's contacts write the friction to carry on into.
    pub fn parts(&mut self) -> (&Vectors<T>, &Vectors<T>, [&mut [T]; 3]) {
        (&self.carried, &self.before, self.next.axes_mut())
    }

    /// Makes what this step carries on the friction the next step is given.
    pub fn end(&mut self) {
        std::mem::swap(&mut self.carried, &mut self.next);
    }
}

impl<T: Real> BandFriction<'_, T> {
    /// The first `count` particles, borrowed.
    pub fn first(&mut self, count: usize) -> BandFriction<'_, T> {
        let [a, b, c] = &mut self.next;
        BandFriction {
            carried: self.carried.map(|a| &a[..count]),
            before: self.before.map(|a| &a[..count]),
            next: [&mut a[..count], &mut b[..count], &mut c[..count]],
        }
    }

    /// Particle `p`'s carried friction and velocity before it.
    #[inline(always)]
    pub fn get(&self, p: usize) -> (Vec3<T>, Vec3<T>) {
        let at = |a: [&[T]; 3]| Vec3::new(a[0][p], a[1][p], a[2][p]);
        (at(self.carried), at(self.before))
    }

    /// Sets the friction particle `p` carries on.
    #[inline(always)]
    pub fn set(&mut self, p: usize, next: Vec3<T>) {
        let next = next.to_array();
        for (axis, value) in self.next.iter_mut().zip(next) {
            axis[p] = value;
        }
    }

    /// For the [`LANES`] particles from `first`, lane by lane: the carried friction and the
    /// velocity before it, or zeros without friction.
    #[inline(always)]
    pub fn lanes(friction: Option<&Self>, first: usize) -> [[Vec3<T>; LANES]; 2] {
        let Some(f) = friction else { return [[Vec3::ZERO; LANES]; 2] };
        let pairs: [(Vec3<T>, Vec3<T>); LANES] = std::array::from_fn(|lane| f.get(first + lane));
        [pairs.map(|(carried, _)| carried), pairs.map(|(_, before)| before)]
    }

    /// Sets the friction carried on by the lanes from `first` that `hit`.
    #[inline(always)]
    pub fn set_lanes(&mut self, first: usize, hit: [bool; LANES], next: &[Vec3<T>; LANES]) {
        for lane in (0..LANES).filter(|&lane| hit[lane]) {
            self.set(first + lane, next[lane]);
        }
    }
}
