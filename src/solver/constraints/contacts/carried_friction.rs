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
//! A particle that friction stopped within Coulomb's cone is stuck: the next solve holds it in
//! all three directions, with the same stiffness, to an anchor, the point where it stopped. Held
//! along the normal alone, its tangential balance would rest on the carried friction, which the
//! projection takes back from the velocity (not the position) whenever the step's bound is the
//! smaller, and on a curved surface such particles kept moving at the frame interval
//! (`docs/decisions.md`, "Static friction held in the solve by an anchor spring"). A stuck
//! particle is given no carried friction: its anchor spring is its friction. After the solve, the
//! spring's impulse `κ / h (a - x)` at the step's end is checked against Coulomb's cone, its
//! normal part and the projection's normal change as the load. Within the cone the particle stays
//! stuck to the same anchor, so it cannot creep. Beyond it, it slides: it keeps the velocity the
//! solve gave it (the spring was its friction there), is held along the normal only, so that no
//! spring drags on its motion, and carries no friction into the next step, whose own response
//! gives it kinetic friction; from then on it carries its steady friction as any sliding
//! particle. A stuck particle is let go when nothing presses it to the surface.
//!
//! The stage exists only for implicit Euler: seven vectors and two flags per particle, filled and
//! read once per step. The explicit integrators take steps small enough for their creep, `h a_t`,
//! to be small, and with friction carried the symplectic reference drape of the contact
//! estimate's tests no longer converges as its step halves, so they keep the projection alone
//! (`docs/decisions.md`, "Friction carried into the next step").

use std::ops::Range;

use crate::solver::forces::spring_blocks::LANES;
use crate::solver::integrators::implicit::Holds;
use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::state::State;

/// How stiffly a solve holds a particle against the surface it touched: `κ` in the stiffness
/// `κ m / h²` along the contact normal. The solve then takes a held particle inward by `1 / 301`
/// of what it would without. Any `κ` from 30 to 1,000 brings the 128² sphere drape at 1/120 s to
/// within 3 mm of its converged lowest point; at the frame interval, where `κ m / h²` is weakest
/// against the springs, 300 is the one of 100, 300 and 1,000 that brings it to rest whatever the
/// solve's small errors (`docs/decisions.md`, "The hold's stiffness, `κ`, raised to 300").
pub(crate) const HOLD_STIFFNESS: f64 = 300.0;

/// How near a surface, in metres, a held particle that the projection did not stop again must
/// stay to be held in the next solve too: a particle lying still on a curved surface, or one the
/// held spring kept exactly on it, can end a rounding error outside.
const HOLD_REACH: f64 = 1e-4;

/// What one step gives each particle or carries on into the next: the friction, as a change of
/// velocity; the normal of the contact the solve holds (zero where none is); whether the particle
/// is stuck; and the anchor a stuck particle is held to (read only where it is stuck).
#[derive(Clone, Debug)]
struct Carry<T> {
    friction: Vectors<T>,
    held: Vectors<T>,
    stuck: Vec<bool>,
    anchors: Vectors<T>,
}

impl<T: Real> Carry<T> {
    fn new(particles: usize) -> Self {
        Self {
            friction: Vectors::zeros(particles),
            held: Vectors::zeros(particles),
            stuck: vec![false; particles],
            anchors: Vectors::zeros(particles),
        }
    }
}

/// What the step was given, the velocities before its friction was given, and what it carries on.
#[derive(Clone, Debug)]
pub(super) struct CarriedFriction<T> {
    given: Carry<T>,
    before: Vectors<T>,
    next: Carry<T>,
}

/// Where a band's contacts write what the step carries on: the friction and the normal to hold,
/// then the anchor and whether the particle is stuck.
pub(super) type NextRows<'a, T> =
    (([&'a mut [T]; 3], [&'a mut [T]; 3]), ([&'a mut [T]; 3], [&'a mut [bool]; 1]));

/// One band's share: what the step was given (the friction carried into it, the velocities before
/// it, the contacts its solve held and the stuck particles' anchors), and where what it carries on
/// is written.
pub(super) struct BandFriction<'a, T> {
    pub carried: [&'a [T]; 3],
    pub before: [&'a [T]; 3],
    pub held: [&'a [T]; 3],
    pub stuck: &'a [bool],
    pub anchors: [&'a [T]; 3],
    /// `κ / h`: the anchor spring's impulse per metre of stretch, as a change of velocity.
    pub hold_rate: T,
    pub next: NextRows<'a, T>,
}

/// One particle's part of what a step was given: the friction carried into it, the velocity
/// before that, the normal of the contact the step's solve held (zero if none), and whether it was
/// stuck, to which anchor, with the anchor spring's impulse per metre of stretch.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Carried<T> {
    pub friction: Vec3<T>,
    pub before: Vec3<T>,
    pub held: Vec3<T>,
    pub stuck: bool,
    pub anchor: Vec3<T>,
    pub hold_rate: T,
}

/// What a contact's response reads of what the step gave the particle ([`respond`](super::respond)).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Given<T> {
    /// The friction the particle was already given in the step, as a change of velocity: the
    /// carried friction, or for a stuck particle the anchor spring's impulse.
    pub friction: Vec3<T>,
    /// The factor on the projection's normal change in the normal impulse that bounds friction.
    pub scale: T,
    /// The normal impulse of the stuck particle's anchor spring, which bounds friction too.
    pub load: T,
    /// Whether the particle is stuck: its friction acts while anything presses it to the surface,
    /// even when it does not approach it.
    pub stuck: bool,
}

/// What one particle carries on into the next step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Next<T> {
    pub friction: Vec3<T>,
    pub hold: Vec3<T>,
    pub stuck: bool,
    pub anchor: Vec3<T>,
}

impl<T: Real> Next<T> {
    /// Nothing carried on.
    pub const NONE: Self = Self { friction: Vec3::ZERO, hold: Vec3::ZERO, stuck: false, anchor: Vec3::ZERO };
}

impl<T: Real> Carried<T> {
    /// What the response reads, for a particle whose step ended at `end`, in contact with normal
    /// `normal`. A stuck particle was given the anchor spring's impulse `κ / h (a - end)` by the
    /// solve, and that impulse's normal part is its load; a held one bounds its friction by the
    /// whole normal impulse, the held spring's `κ` times the projection's.
    #[inline(always)]
    pub fn given(&self, end: Vec3<T>, normal: Vec3<T>) -> Given<T> {
        let pull = (self.anchor - end) * self.hold_rate;
        let held = self.held != Vec3::ZERO;
        let scale = if held & !self.stuck { T::from_f64(1.0 + HOLD_STIFFNESS) } else { T::ONE };
        Given {
            friction: if self.stuck { pull } else { self.friction },
            scale,
            load: if self.stuck { pull.dot(normal) } else { T::ZERO },
            stuck: self.stuck,
        }
    }
}

impl<T: Real> CarriedFriction<T> {
    pub fn new(particles: usize) -> Self {
        Self { given: Carry::new(particles), before: Vectors::zeros(particles), next: Carry::new(particles) }
    }

    /// Gives each particle the friction carried into this step, remembering its velocity before,
    /// and clears what the step will carry on.
    pub fn begin(&mut self, velocities: &mut Vectors<T>) {
        self.next.held.fill(Vec3::ZERO);
        self.next.stuck.fill(false);
        let ([v0, v1, v2], [c0, c1, c2]) = (velocities.axes_mut(), self.given.friction.axes());
        let ([b0, b1, b2], [n0, n1, n2]) = (self.before.axes_mut(), self.next.friction.axes_mut());
        for (v, c, b, n) in [(v0, c0, b0, n0), (v1, c1, b1, n1), (v2, c2, b2, n2)] {
            for (((v, &c), b), n) in v.iter_mut().zip(c).zip(b.iter_mut()).zip(n.iter_mut()) {
                *b = *v;
                *v += c;
                *n = T::ZERO;
            }
        }
    }

    /// What the step was given, to be cut into bands ([`GivenParts::band`]), with the rows that the
    /// step's contacts write what they carry on into.
    pub fn parts(&mut self) -> (GivenParts<'_, T>, NextRows<'_, T>) {
        let Self { given, before, next } = self;
        let rows = (
            (next.friction.axes_mut(), next.held.axes_mut()),
            (next.anchors.axes_mut(), [&mut next.stuck[..]]),
        );
        (GivenParts { given, before }, rows)
    }

    /// The normal of each particle's contact that the next solve holds (zero where none is), and
    /// which of them are stuck, to which anchors.
    pub fn holds(&self) -> Holds<'_, T> {
        Holds { normals: &self.given.held, anchored: Some((&self.given.anchors, &self.given.stuck)) }
    }

    /// Keeps holding each particle the step's solve held and the projection did not stop again
    /// (so it carries nothing on yet), if it is within [`HOLD_REACH`] of a surface, by `gap`, and
    /// did not move away from it by more than a rounding error over the step of `h`; it keeps the
    /// friction it was given, and stays stuck to its anchor if it was.
    pub fn keep_holding(&mut self, state: &State<T>, h: T, gap: impl Fn(Vec3<T>) -> T) {
        let (reach, away) = (T::from_f64(HOLD_REACH), T::from_f64(HOLD_REACH * 1e-3));
        for p in 0..self.given.held.len() {
            let n = self.given.held.get(p);
            if n == Vec3::ZERO || self.next.held.get(p) != Vec3::ZERO {
                continue;
            }
            let leaving = state.velocities.get(p).dot(n) * h;
            if leaving < away && gap(state.positions.get(p)) < reach {
                self.next.held.set(p, n);
                self.next.friction.set(p, self.given.friction.get(p));
                self.next.stuck[p] = self.given.stuck[p];
                self.next.anchors.set(p, self.given.anchors.get(p));
            }
        }
    }

    /// Makes what this step carries on what the next step is given.
    pub fn end(&mut self) {
        std::mem::swap(&mut self.given, &mut self.next);
    }
}

/// What a step was given and the velocities before, borrowed while the step writes what it
/// carries on.
#[derive(Clone, Copy)]
pub(super) struct GivenParts<'a, T> {
    given: &'a Carry<T>,
    before: &'a Vectors<T>,
}

impl<'a, T: Real> GivenParts<'a, T> {
    /// The share of the particles in `particles`, with the rows `next` of them to write into, for
    /// a step of `h`.
    pub fn band(self, particles: Range<usize>, next: NextRows<'a, T>, h: T) -> BandFriction<'a, T> {
        BandFriction {
            carried: self.given.friction.range(particles.clone()),
            before: self.before.range(particles.clone()),
            held: self.given.held.range(particles.clone()),
            anchors: self.given.anchors.range(particles.clone()),
            stuck: &self.given.stuck[particles],
            hold_rate: T::from_f64(HOLD_STIFFNESS) / h,
            next,
        }
    }
}

impl<T: Real> BandFriction<'_, T> {
    /// The first `count` particles, borrowed.
    pub fn first(&mut self, count: usize) -> BandFriction<'_, T> {
        let ((friction, held), (anchors, [stuck])) = &mut self.next;
        fn cut<'a, T>(axes: &'a mut [&mut [T]; 3], count: usize) -> [&'a mut [T]; 3] {
            let [a, b, c] = axes;
            [&mut a[..count], &mut b[..count], &mut c[..count]]
        }
        BandFriction {
            carried: self.carried.map(|a| &a[..count]),
            before: self.before.map(|a| &a[..count]),
            held: self.held.map(|a| &a[..count]),
            anchors: self.anchors.map(|a| &a[..count]),
            stuck: &self.stuck[..count],
            hold_rate: self.hold_rate,
            next: ((cut(friction, count), cut(held, count)), (cut(anchors, count), [&mut stuck[..count]])),
        }
    }

    /// Particle `p`'s part.
    #[inline(always)]
    pub fn get(&self, p: usize) -> Carried<T> {
        let at = |a: [&[T]; 3]| Vec3::new(a[0][p], a[1][p], a[2][p]);
        Carried {
            friction: at(self.carried),
            before: at(self.before),
            held: at(self.held),
            stuck: self.stuck[p],
            anchor: at(self.anchors),
            hold_rate: self.hold_rate,
        }
    }

    /// Sets what particle `p` carries on.
    #[inline(always)]
    pub fn set(&mut self, p: usize, next: Next<T>) {
        let ((friction, held), (anchors, [stuck])) = &mut self.next;
        for (axes, value) in [(friction, next.friction), (held, next.hold), (anchors, next.anchor)] {
            for (axis, value) in axes.iter_mut().zip(value.to_array()) {
                axis[p] = value;
            }
        }
        stuck[p] = next.stuck;
    }

    /// For the [`LANES`] particles from `first`, lane by lane, their parts, or nothing carried
    /// without friction.
    #[inline(always)]
    pub fn lanes(friction: Option<&Self>, first: usize) -> [Carried<T>; LANES] {
        let nothing = Carried {
            friction: Vec3::ZERO,
            before: Vec3::ZERO,
            held: Vec3::ZERO,
            stuck: false,
            anchor: Vec3::ZERO,
            hold_rate: T::ZERO,
        };
        let Some(f) = friction else { return [nothing; LANES] };
        std::array::from_fn(|lane| f.get(first + lane))
    }

    /// Sets what the lanes from `first` that `hit` carry on.
    #[inline(always)]
    pub fn set_lanes(&mut self, first: usize, hit: [bool; LANES], next: &[Next<T>; LANES]) {
        for lane in (0..LANES).filter(|&lane| hit[lane]) {
            self.set(first + lane, next[lane]);
        }
    }
}
