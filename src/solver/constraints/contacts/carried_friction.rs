//! What one step's contacts carry into the next, for implicit Euler: the friction that held a
//! particle, so that static friction holds it still instead of letting it creep, and the contact
//! itself, which the next solve holds.
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
//! The same happens along the normal. Left to the projection, the solve moves a particle lying on
//! a collider inward with the sheet's pull and the projection puts it back: every step the two
//! trade spring energy far larger than the sheet's motion, and what the trade does not return
//! keeps a drape moving at small steps (`docs/decisions.md`, "Contacts held in the solve by a
//! stiff normal spring"). So a particle that a fixed collider stopped in one step is held against
//! it in the next solve: the solve adds the stiffness `κ m / h²` along the contact normal `n` to
//! the particle's diagonal ([`HOLD_STIFFNESS`] is `κ`), so that it keeps `1 / (1 + κ)` of its
//! inward motion, and the springs and the rest of the sheet see the surface hold it. The
//! projection still runs after the solve and removes the rest, so nothing ends inside, and the
//! held spring's impulse, `κ` times the projection's, counts in the normal impulse that bounds
//! friction. A held particle stays held while the projection stops it again, or while it stays
//! within [`HOLD_REACH`] of a surface without moving away; one that the sheet pulls off is let go.
//!
//! The stage exists only for implicit Euler: five vectors per particle, filled and read once per
//! step. The explicit integrators take steps small enough for their creep, `h a_t`, to be small,
//! and with friction carried the symplectic reference drape of the contact estimate's tests no
//! longer converges as its step halves, so they keep the projection alone (`docs/decisions.md`,
//! "Friction carried into the next step").

use crate::solver::forces::spring_blocks::LANES;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::state::State;

/// How stiffly a solve holds a particle against the surface it touched: `κ` in the stiffness
/// `κ m / h²` along the contact normal. The solve then takes a held particle inward by a `1 / 101`
/// of what it would without; any `κ` from 30 to 1,000 brings the 128² sphere drape at 1/120 s to
/// within 3 mm of its converged lowest point (`docs/decisions.md`).
pub(crate) const HOLD_STIFFNESS: f64 = 100.0;

/// How near a surface, in metres, a held particle that the projection did not stop again must
/// stay to be held in the next solve too: a particle lying still on a curved surface, or one the
/// held spring kept exactly on it, can end a rounding error outside.
const HOLD_REACH: f64 = 1e-4;

/// Each particle's friction carried into the step, as a change of velocity, the velocities before
/// it was given, and the friction this step carries into the next; and the normal of each
/// particle's contact held in the step's solve (zero where none is), and of those held in the next.
#[derive(Clone, Debug)]
pub(super) struct CarriedFriction<T> {
    carried: Vectors<T>,
    before: Vectors<T>,
    next: Vectors<T>,
    held: Vectors<T>,
    next_held: Vectors<T>,
}

/// One band's share: the friction carried into the step, the velocities before it and the
/// contacts the step's solve held, and where the friction to carry on and the contacts to hold
/// next are written.
pub(super) struct BandFriction<'a, T> {
    pub carried: [&'a [T]; 3],
    pub before: [&'a [T]; 3],
    pub held: [&'a [T]; 3],
    pub next: [&'a mut [T]; 3],
    pub next_held: [&'a mut [T]; 3],
}

/// One particle's part of what a step carries: the friction carried into it, the velocity before
/// that, and the normal of the contact the step's solve held (zero if none).
#[derive(Clone, Copy, Debug)]
pub(super) struct Carried<T> {
    pub friction: Vec3<T>,
    pub before: Vec3<T>,
    pub held: Vec3<T>,
}

impl<T: Real> Carried<T> {
    /// The friction coefficient `mu` scaled for the held spring's share of the normal impulse: the
    /// projection's normal change is `1 / (1 + κ)` of the whole for a held particle.
    #[inline(always)]
    pub fn friction_scale(&self) -> T {
        let held = self.held != Vec3::ZERO;
        if held { T::from_f64(1.0 + HOLD_STIFFNESS) } else { T::ONE }
    }
}

impl<T: Real> CarriedFriction<T> {
    pub fn new(particles: usize) -> Self {
        Self {
            carried: Vectors::zeros(particles),
            before: Vectors::zeros(particles),
            next: Vectors::zeros(particles),
            held: Vectors::zeros(particles),
            next_held: Vectors::zeros(particles),
        }
    }

    /// Gives each particle the friction carried into this step, remembering its velocity before,
    /// and clears what the step will carry on.
    pub fn begin(&mut self, velocities: &mut Vectors<T>) {
        self.next_held.fill(Vec3::ZERO);
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

    /// The carried friction, the velocities before it and the contacts the step's solve held, for
    /// the whole state, and the arrays the step's contacts write the friction to carry on and the
    /// contacts to hold next into.
    #[allow(clippy::type_complexity)]
    pub fn parts(&mut self) -> (&Vectors<T>, &Vectors<T>, &Vectors<T>, [&mut [T]; 3], [&mut [T]; 3]) {
        (&self.carried, &self.before, &self.held, self.next.axes_mut(), self.next_held.axes_mut())
    }

    /// The normal of each particle's contact that the next solve holds, zero where none is.
    pub fn held(&self) -> &Vectors<T> {
        &self.held
    }

    /// Keeps holding each particle the step's solve held and the projection did not stop again
    /// (so it carries nothing on yet), if it is within [`HOLD_REACH`] of a surface, by `gap`, and
    /// did not move away from it by more than a rounding error over the step of `h`; it keeps the
    /// friction it was given, too.
    pub fn keep_holding(&mut self, state: &State<T>, h: T, gap: impl Fn(Vec3<T>) -> T) {
        let (reach, away) = (T::from_f64(HOLD_REACH), T::from_f64(HOLD_REACH * 1e-3));
        for p in 0..self.held.len() {
            let n = self.held.get(p);
            if n == Vec3::ZERO || self.next_held.get(p) != Vec3::ZERO {
                continue;
            }
            let leaving = state.velocities.get(p).dot(n) * h;
            if leaving < away && gap(state.positions.get(p)) < reach {
                self.next_held.set(p, n);
                self.next.set(p, self.carried.get(p));
            }
        }
    }

    /// Makes what this step carries on the friction the next step is given and the contacts its
    /// solve holds.
    pub fn end(&mut self) {
        std::mem::swap(&mut self.carried, &mut self.next);
        std::mem::swap(&mut self.held, &mut self.next_held);
    }
}

impl<T: Real> BandFriction<'_, T> {
    /// The first `count` particles, borrowed.
    pub fn first(&mut self, count: usize) -> BandFriction<'_, T> {
        let [a, b, c] = &mut self.next;
        let [d, e, f] = &mut self.next_held;
        BandFriction {
            carried: self.carried.map(|a| &a[..count]),
            before: self.before.map(|a| &a[..count]),
            held: self.held.map(|a| &a[..count]),
            next: [&mut a[..count], &mut b[..count], &mut c[..count]],
            next_held: [&mut d[..count], &mut e[..count], &mut f[..count]],
        }
    }

    /// Particle `p`'s part.
    #[inline(always)]
    pub fn get(&self, p: usize) -> Carried<T> {
        let at = |a: [&[T]; 3]| Vec3::new(a[0][p], a[1][p], a[2][p]);
        Carried { friction: at(self.carried), before: at(self.before), held: at(self.held) }
    }

    /// Sets the friction particle `p` carries on and the normal of its contact to hold next (zero
    /// for none).
    #[inline(always)]
    pub fn set(&mut self, p: usize, next: Vec3<T>, hold: Vec3<T>) {
        for (axes, value) in [(&mut self.next, next), (&mut self.next_held, hold)] {
            for (axis, value) in axes.iter_mut().zip(value.to_array()) {
                axis[p] = value;
            }
        }
    }

    /// For the [`LANES`] particles from `first`, lane by lane, their parts, or nothing carried
    /// without friction.
    #[inline(always)]
    pub fn lanes(friction: Option<&Self>, first: usize) -> [Carried<T>; LANES] {
        let nothing = Carried { friction: Vec3::ZERO, before: Vec3::ZERO, held: Vec3::ZERO };
        let Some(f) = friction else { return [nothing; LANES] };
        std::array::from_fn(|lane| f.get(first + lane))
    }

    /// Sets what the lanes from `first` that `hit` carry on: friction and the contact to hold.
    #[inline(always)]
    pub fn set_lanes(&mut self, first: usize, hit: [bool; LANES], next: &[(Vec3<T>, Vec3<T>); LANES]) {
        for lane in (0..LANES).filter(|&lane| hit[lane]) {
            self.set(first + lane, next[lane].0, next[lane].1);
        }
    }
}
