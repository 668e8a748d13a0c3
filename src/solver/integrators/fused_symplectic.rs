//! Symplectic Euler fused into the grid spring sweep: the whole step of a scene that is one
//! cloth and nothing but gravity, drag and its springs, in a single pass over the particles.
//!
//! The sweep ([`kernel`](crate::solver::forces::grid::kernel)) hands each row its total force
//! as soon as the row is complete; [`SymplecticUpdate`] turns it straight into the row's new
//! velocities and positions, so the forces never leave the row accumulators. It also sums, down
//! the columns, what the stability watch needs over the new state. The update's arithmetic is
//! that of the unfused step in [`euler`](super::euler).
//!
//! The sink's methods are `#[inline]` because the sweep that calls them lives in another module,
//! hence another codegen unit, where they would otherwise stay calls.

use crate::solver::forces::body::BodyForce;
use crate::solver::forces::dynamics::Dynamics;
use crate::solver::forces::grid::BodyTerms;
use crate::solver::forces::grid::GridSprings;
use crate::solver::forces::grid::bands::in_bands;
use crate::solver::forces::grid::kernel::RowSink;
use crate::solver::math::real::Real;
use crate::solver::state::State;

/// One symplectic Euler step from `state` into `next` in a single pass over the particles, the
/// forces never stored (see [`GridSprings::symplectic_step`]), for a scene that
/// [has one](Dynamics::has_fused_passes). Returns the stability watch's sums over `next`
/// (`Σ m |v|²` and the sum of every position component), or `None`, having done nothing, for
/// any other scene.
pub(crate) fn step<T: Real>(
    dynamics: &mut Dynamics<T>,
    state: &State<T>,
    next: &mut State<T>,
    h: T,
) -> Option<(T, T)> {
    let (grid, inputs) = dynamics.fused_grid(&state.positions, &state.velocities)?;
    Some(grid.symplectic_step(&inputs, h, state, next))
}

impl<T: Real> GridSprings<T> {
    /// One symplectic Euler step of the body from `state` into `next` (`v' = v + h f / m`, then
    /// `x' = x + h v'`), where `f` is gravity, drag and the springs. The forces never leave the
    /// row accumulators. Returns `Σ m |v'|²` and the sum of every component of `x'`, for the
    /// stability watch.
    pub fn symplectic_step(
        &mut self,
        inputs: &BodyTerms<T>,
        h: T,
        state: &State<T>,
        next: &mut State<T>,
    ) -> (T, T) {
        let range = self.particles();
        let range_of_body = range.clone();
        let (x, v) = (state.positions.range(range.clone()), state.velocities.range(range.clone()));
        let masses = &inputs.masses[range.clone()];
        let inverse_masses = &inputs.inverse_masses[range.clone()];
        let nx = self.layout.nx;
        let [px, py, pz] = next.positions.range_mut(range.clone());
        let [vx, vy, vz] = next.velocities.range_mut(range);
        let outputs = [px, py, pz, vx, vy, vz];
        let bands = self.pass(|layout, bands| {
            in_bands(bands, nx, outputs, &|band, [px, py, pz, vx, vy, vz]| {
                let mut sink = SymplecticUpdate {
                    offset: band.rows.start * nx,
                    nx,
                    x,
                    v,
                    masses,
                    inverse_masses,
                    gravity: inputs.gravity.to_array(),
                    drag: inputs.drag,
                    extra: inputs.extra.map(|f| f.map(|axis| &axis[range_of_body.clone()])),
                    h,
                    positions: [px, py, pz],
                    velocities: [vx, vy, vz],
                    columns: band.take_columns(),
                };
                band.sweep(layout, x, v, &mut sink);
                band.put_back_columns(sink.columns);
            })
        });
        // Band by band, in order: the same sums whichever thread ran which band.
        bands.iter().fold((T::ZERO, T::ZERO), |(k, p), band| (k + band.sums.0, p + band.sums.1))
    }
}

/// A sink that turns each row's force straight into symplectic Euler's new state.
struct SymplecticUpdate<'a, T> {
    /// The band's first particle within the body.
    offset: usize,
    nx: usize,
    x: [&'a [T]; 3],
    v: [&'a [T]; 3],
    masses: &'a [T],
    inverse_masses: &'a [T],
    gravity: [T; 3],
    drag: T,
    /// Bending forces over the body's particles, if any.
    extra: Option<[&'a [T]; 3]>,
    h: T,
    /// The band's new positions and velocities.
    positions: [&'a mut [T]; 3],
    velocities: [&'a mut [T]; 3],
    /// Per column, summed over rows: `Σ m |v|²` and `Σ (x + y + z)`. Summing down the columns
    /// keeps the loop a plain element-wise one, which vectorises, where a sum along the row would
    /// not.
    columns: [Vec<T>; 2],
}

impl<T: Real> RowSink<T> for SymplecticUpdate<'_, T> {
    #[inline]
    fn start(&mut self, row: usize, force: [&mut [T]; 3]) {
        let body = BodyForce {
            offset: self.offset,
            nx: self.nx,
            v: self.v,
            masses: self.masses,
            gravity: self.gravity,
            drag: self.drag,
            extra: self.extra,
        };
        body.start(row, force);
    }

    #[inline]
    fn finish(&mut self, row: usize, force: [&mut [T]; 3]) {
        let local = row * self.nx..(row + 1) * self.nx;
        let cells = self.offset + local.start..self.offset + local.end;
        let inverse_masses = &self.inverse_masses[cells.clone()];
        let h = self.h;
        let old = self.x.iter().zip(self.v).zip(force);
        for (((x, v), f), (new_x, new_v)) in
            old.zip(self.positions.iter_mut().zip(self.velocities.iter_mut()))
        {
            let (x, v) = (&x[cells.clone()], &v[cells.clone()]);
            let new = new_x[local.clone()].iter_mut().zip(&mut new_v[local.clone()]);
            for (((new_x, new_v), (&x, &v)), (&f, &w)) in
                new.zip(x.iter().zip(v)).zip(f.iter().zip(inverse_masses))
            {
                let velocity = (v + f * w * h).kept_speed();
                *new_v = velocity;
                *new_x = x + velocity * h;
            }
        }
        let [px, py, pz] = self.positions.each_ref().map(|axis| &axis[local.clone()]);
        let [vx, vy, vz] = self.velocities.each_ref().map(|axis| &axis[local.clone()]);
        let [kinetic, position] = &mut self.columns;
        let velocities = vx.iter().zip(vy).zip(vz);
        let positions = px.iter().zip(py).zip(pz);
        let sums = kinetic.iter_mut().zip(position.iter_mut()).zip(&self.masses[cells]);
        for (((kinetic, position), &m), (((&vx, &vy), &vz), ((&x, &y), &z))) in
            sums.zip(velocities.zip(positions))
        {
            *kinetic += m * (vx * vx + vy * vy + vz * vz);
            *position += x + y + z;
        }
    }
}
