//! Smoothed-aggregation algebraic multigrid (Vaněk, Mandel and Brezina, 1996; for cloth,
//! Tamstorf, Jones and McCormick, 2015) on the 3×3 block system of any spring graph: the
//! spring-list solver's conjugate-gradient preconditioner.
//!
//! What depends on the graph alone is built once. Particles are grouped greedily into
//! aggregates of a root and its strong neighbours, a spring being strong when its stiffness is
//! at least [`STRENGTH`] of the stiffest spring at either end (so a mesh's edges are, and its
//! weak bending springs across the edges are not); each coarser level groups the aggregates of
//! the one above the same way, over the summed stiffness between them. Several bodies are
//! several components of the graph and never share an aggregate. Pinned particles belong to
//! none: their rows and columns are held (the identity), as the solve holds them. The patterns
//! of the prolongators and of the Galerkin products, and where each product's terms go, are
//! planned then too.
//!
//! Each step refills the values. Level 0 is the step's system from its spring blocks, masses
//! and bending hinges, optionally filtered by a per-particle projection `S` (the operator becomes
//! `S A S + (I − S)`, as for particles held against a collider). On each level the tentative
//! prolongator carries the three translations (each aggregate's particles move together, scaled
//! so that its columns are orthonormal); one damped Jacobi step smooths it,
//! `P = (I − ω D⁻¹ A) P₀` with `ω = 4 / (3 λ)` and `λ` the largest eigenvalue of `D⁻¹ A` by power
//! iteration; the coarse operator is the Galerkin product `Pᵀ A P`, made exactly symmetric.
//!
//! The preconditioner is one V-cycle: a forward block Gauss-Seidel sweep before the coarse
//! correction and a backward one after it, and a dense Cholesky factorisation in `f64` on the
//! coarsest level. The backward sweep is the forward one's adjoint and the coarse operators are
//! Galerkin products, so the cycle is symmetric positive definite, as conjugate gradients needs.
//!
//! On a dense graph (a lattice's springs reach 26 neighbours and bend across two) a refill can
//! take as long as many solves, so it looks at the step's interrupt every [`ROWS_PER_LOOK`] rows
//! of each product and gives up when it is raised; the next refill starts from its clearing, so a
//! refill given up leaves nothing behind.

use super::block_sparse::{Block, BlockCsr};
use super::dense_cholesky::DenseCholesky;
use crate::solver::forces::bending::BendingElements;
use crate::solver::integrators::Interrupted;
use crate::solver::interrupt::Interrupt;
use crate::solver::math::real::Real;
use crate::solver::math::sym3::Sym3;
use crate::solver::math::vec3::Vec3;
use crate::solver::model::Spring;

/// A spring is strong when its stiffness is at least this fraction of the stiffest spring at
/// either of its ends.
pub(crate) const STRENGTH: f64 = 0.25;

/// Coarsening stops at a level of at most this many particles, which is factored directly.
const COARSEST_PARTICLES: usize = 64;

/// Coarsening also stops when a level would keep more than this fraction of its particles (a
/// graph with few springs); a last level still too large to factor is smoothed instead.
const STALLED: f64 = 0.8;

/// The largest last level factored directly; a larger one gets a forward and a backward sweep.
const DENSE_PARTICLES: usize = 400;

/// Power iterations for the largest eigenvalue of `D⁻¹ A` on each level.
const POWER_ITERATIONS: usize = 8;

const NONE: u32 = u32::MAX;

/// Rows of a refill's product between two looks at the interrupt.
const ROWS_PER_LOOK: usize = 1024;

/// `Err(Interrupted)` at every [`ROWS_PER_LOOK`]-th row once `interrupt` is raised.
fn look(row: usize, interrupt: Option<&Interrupt>) -> Result<(), Interrupted> {
    let raised = row.is_multiple_of(ROWS_PER_LOOK) && interrupt.is_some_and(Interrupt::is_raised);
    if raised { Err(Interrupted) } else { Ok(()) }
}

/// What the step's system is made of: `A = diag(mass) + Σ_s ±S_s + (a C + b D)` of the hinges.
pub(crate) struct FineSystem<'a, T> {
    /// Per particle: the mass part of the diagonal, `m (1 + h · drag)`.
    pub mass_diagonal: &'a [T],
    /// Per spring: its block `h D + h² K`.
    pub spring_blocks: &'a [Sym3<T>],
    /// The hinges with the factors `(a, b)` of their stiffness and damping matrices.
    pub bending: Option<(&'a BendingElements<T>, T, T)>,
    /// Blocks added to particles' diagonals: the contacts the solve holds.
    pub held_blocks: &'a [(usize, Sym3<T>)],
}

/// The hierarchy, its transfers and the coarsest level's solve.
#[derive(Debug)]
pub(crate) struct Aggregation<T> {
    levels: Vec<Level<T>>,
    /// `transfers[l]` goes between levels `l` and `l + 1`.
    transfers: Vec<Transfer<T>>,
    fine: FineSlots,
    coarsest: Option<DenseCholesky>,
}

/// Where each term of the step's system goes in level 0.
#[derive(Debug)]
struct FineSlots {
    held: Vec<bool>,
    /// Per spring: the entries `(i, i)`, `(j, j)`, `(i, j)`, `(j, i)`; `NONE` for those a
    /// held end removes.
    springs: Vec<[u32; 4]>,
    /// Per hinge entry, in the order [`BendingElements::for_each_entry`] gives them.
    hinges: Vec<u32>,
}

#[derive(Debug)]
struct Level<T> {
    operator: BlockCsr<T>,
    /// Each row's diagonal entry.
    diagonal: Vec<u32>,
    /// Each entry's transpose.
    transposes: Vec<u32>,
    inverse_diagonal: Vec<Block<T>>,
    rhs: Vec<Vec3<T>>,
    solution: Vec<Vec3<T>>,
    residual: Vec<Vec3<T>>,
}

#[derive(Debug)]
struct Transfer<T> {
    /// Per fine particle: its tentative prolongator entry `1 / √(aggregate size)`, or zero.
    tentative: Vec<T>,
    /// Per fine particle: its own aggregate's entry in the prolongator, or `NONE`.
    own: Vec<u32>,
    /// The damping of the last smoothing.
    omega: T,
    prolongator: BlockCsr<T>,
    /// Per fine operator entry `(i, j)`: the prolongator's entry `(i, aggregate of j)`, or `NONE`.
    smoothing_slots: Vec<u32>,
    /// `A P`.
    product: BlockCsr<T>,
    /// Per term of `A P`, row by row, the entries of `A` and the rows of `P` they meet: where
    /// the term goes.
    product_slots: Vec<u32>,
    /// Per term of `Pᵀ (A P)`, fine row by fine row: where the term goes in the coarse operator.
    galerkin_slots: Vec<u32>,
}

/// A level's graph: per particle, its neighbours with the summed stiffness between them.
type Graph = Vec<Vec<(u32, f64)>>;

impl<T: Real> Aggregation<T> {
    /// The hierarchy of the spring graph of `particles` particles, `held` marking the pinned
    /// ones, with at most `depth` levels: with one, the preconditioner is a symmetric block
    /// Gauss-Seidel sweep (or a direct solve of a small system).
    pub fn with_depth(
        particles: usize,
        springs: &[Spring<T>],
        bending: Option<&BendingElements<T>>,
        held: &[bool],
        depth: usize,
    ) -> Self {
        let free = |p: usize| !held[p];
        let mut rows: Vec<Vec<u32>> = (0..particles).map(|p| vec![p as u32]).collect();
        let mut graph: Graph = vec![Vec::new(); particles];
        for s in springs {
            let (i, j) = (s.i as usize, s.j as usize);
            if i != j && free(i) && free(j) {
                rows[i].push(j as u32);
                rows[j].push(i as u32);
                graph[i].push((j as u32, s.stiffness.to_f64()));
                graph[j].push((i as u32, s.stiffness.to_f64()));
            }
        }
        let mut hinge_pairs = Vec::new();
        if let Some(hinges) = bending {
            hinges.for_each_entry(|p, q, _, _| {
                if p != q && free(p) && free(q) {
                    rows[p].push(q as u32);
                }
                hinge_pairs.push((p, q));
            });
        }
        let operator = BlockCsr::from_rows(particles, rows);
        let slot = |p: usize, q: usize| {
            if free(p) && free(q) { operator.slot(p, q).map_or(NONE, |e| e as u32) } else { NONE }
        };
        let fine = FineSlots {
            held: held.to_vec(),
            springs: springs
                .iter()
                .map(|s| {
                    let (i, j) = (s.i as usize, s.j as usize);
                    if i == j { [NONE; 4] } else { [slot(i, i), slot(j, j), slot(i, j), slot(j, i)] }
                })
                .collect(),
            hinges: hinge_pairs.iter().map(|&(p, q)| slot(p, q)).collect(),
        };
        let mut levels = vec![Level::new(operator)];
        let mut transfers = Vec::new();
        let mut included: Vec<bool> = held.iter().map(|&h| !h).collect();
        for neighbours in &mut graph {
            merge_duplicates(neighbours);
        }
        while levels.len() < depth {
            let count = included.iter().filter(|&&i| i).count();
            if count <= COARSEST_PARTICLES {
                break;
            }
            let (aggregate, aggregates) = aggregate(&graph, &included);
            if aggregates as f64 > STALLED * count as f64 {
                break;
            }
            let fine_operator = &levels.last().expect("level 0 is there").operator;
            let (transfer, coarse) = Transfer::new(fine_operator, &aggregate, aggregates);
            graph = coarse_graph(&graph, &aggregate, aggregates);
            included = vec![true; aggregates];
            transfers.push(transfer);
            levels.push(Level::new(coarse));
        }
        let last = levels.last().expect("level 0 is there").operator.rows();
        let coarsest = (last <= DENSE_PARTICLES).then(|| DenseCholesky::new(last));
        Self { levels, transfers, fine, coarsest }
    }

    /// The number of levels.
    #[cfg(test)]
    pub fn depth(&self) -> usize {
        self.levels.len()
    }

    /// Refills every level from the step's system, filtered by `filter` (a projection per
    /// particle) when given; gives up part-way as soon as `interrupt` is raised.
    pub fn refill(
        &mut self,
        system: &FineSystem<'_, T>,
        filter: Option<&[Sym3<T>]>,
        interrupt: Option<&Interrupt>,
    ) -> Result<(), Interrupted> {
        self.fill_fine(system, filter);
        for l in 0..self.transfers.len() {
            let (finer, coarser) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut finer[l], &mut coarser[0]);
            fine.update_inverse_diagonal();
            let lambda = fine.largest_eigenvalue();
            let omega = T::from_f64(4.0 / (3.0 * lambda));
            self.transfers[l].refill(fine, omega, &mut coarse.operator, interrupt)?;
            coarse.operator.symmetrise(&coarse.transposes);
        }
        let last = self.levels.last_mut().expect("level 0 is there");
        last.update_inverse_diagonal();
        if let Some(dense) = &mut self.coarsest {
            let operator = &last.operator;
            dense.clear();
            for r in 0..operator.rows() {
                for e in operator.row(r) {
                    let c = operator.column(e);
                    for (a, row) in operator.blocks[e].0.iter().enumerate() {
                        for (b, &value) in row.iter().enumerate() {
                            dense.add(3 * r + a, 3 * c + b, value.to_f64());
                        }
                    }
                }
            }
            dense.factor(|p| last.inverse_diagonal[p].0.map(|row| row.map(|v| v.to_f64())));
        }
        Ok(())
    }

    fn fill_fine(&mut self, system: &FineSystem<'_, T>, filter: Option<&[Sym3<T>]>) {
        let level = &mut self.levels[0];
        let held = &self.fine.held;
        let operator = &mut level.operator;
        operator.clear();
        for (p, &m) in system.mass_diagonal.iter().enumerate() {
            let d = level.diagonal[p] as usize;
            operator.blocks[d] = Block::diagonal(if held[p] { T::ONE } else { m });
        }
        for &(p, ref block) in system.held_blocks.iter().filter(|&&(p, _)| !held[p]) {
            operator.blocks[level.diagonal[p] as usize].add_scaled(T::ONE, &Block::from_sym(block));
        }
        for (slots, block) in self.fine.springs.iter().zip(system.spring_blocks) {
            let block = Block::from_sym(block);
            for (k, &e) in slots.iter().enumerate() {
                if e != NONE {
                    operator.blocks[e as usize].add_scaled(if k < 2 { T::ONE } else { -T::ONE }, &block);
                }
            }
        }
        if let Some((hinges, a, b)) = system.bending {
            let (a, b) = (a.to_f64(), b.to_f64());
            let mut k = 0;
            hinges.for_each_entry(|_, _, c, d| {
                let e = self.fine.hinges[k];
                k += 1;
                if e != NONE {
                    let g = T::from_f64(a * c + b * d);
                    for axis in 0..3 {
                        operator.blocks[e as usize].0[axis][axis] += g;
                    }
                }
            });
        }
        if let Some(filter) = filter {
            for p in 0..operator.rows() {
                if held[p] {
                    continue;
                }
                let s = Block::from_sym(&filter[p]);
                for e in operator.row(p) {
                    let q = operator.column(e);
                    let filtered = s.times(&operator.blocks[e]).times(&Block::from_sym(&filter[q]));
                    operator.blocks[e] = filtered;
                }
                let d = level.diagonal[p] as usize;
                let mut complement = Block::identity();
                complement.add_scaled(-T::ONE, &s);
                operator.blocks[d].add_scaled(T::ONE, &complement);
            }
            operator.symmetrise(&level.transposes);
        }
    }

    /// `z = M⁻¹ r`: one V-cycle from zero.
    pub fn apply(&mut self, r: &[Vec3<T>], z: &mut [Vec3<T>]) {
        self.levels[0].rhs.copy_from_slice(r);
        let last = self.levels.len() - 1;
        for l in 0..last {
            let (finer, coarser) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut finer[l], &mut coarser[0]);
            fine.solution.fill(Vec3::ZERO);
            fine.sweep(false);
            fine.update_residual();
            self.transfers[l].prolongator.apply_transpose(&fine.residual, &mut coarse.rhs);
        }
        let coarsest = &mut self.levels[last];
        match &mut self.coarsest {
            Some(dense) => {
                for (w, v) in dense.work().chunks_exact_mut(3).zip(&coarsest.rhs) {
                    w.copy_from_slice(&v.to_dvec3().to_array());
                }
                dense.solve();
                for (x, w) in coarsest.solution.iter_mut().zip(dense.work().chunks_exact(3)) {
                    *x = Vec3::new(T::from_f64(w[0]), T::from_f64(w[1]), T::from_f64(w[2]));
                }
            }
            None => {
                coarsest.solution.fill(Vec3::ZERO);
                coarsest.sweep(false);
                coarsest.sweep(true);
            }
        }
        for l in (0..last).rev() {
            let (finer, coarser) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut finer[l], &coarser[0]);
            self.transfers[l].prolongator.apply_add(&coarse.solution, &mut fine.solution);
            fine.sweep(true);
        }
        z.copy_from_slice(&self.levels[0].solution);
    }
}

impl<T: Real> Level<T> {
    fn new(operator: BlockCsr<T>) -> Self {
        let n = operator.rows();
        let diagonal =
            (0..n).map(|p| operator.slot(p, p).expect("every row has its diagonal") as u32).collect();
        let transposes = operator.transpose_slots();
        Self {
            operator,
            diagonal,
            transposes,
            inverse_diagonal: vec![Block::ZERO; n],
            rhs: vec![Vec3::ZERO; n],
            solution: vec![Vec3::ZERO; n],
            residual: vec![Vec3::ZERO; n],
        }
    }

    fn update_inverse_diagonal(&mut self) {
        for (inverse, &d) in self.inverse_diagonal.iter_mut().zip(&self.diagonal) {
            *inverse = Block::from_sym(&self.operator.blocks[d as usize].symmetric_part().inverse());
        }
    }

    /// The largest eigenvalue of `D⁻¹ A` by power iteration from a fixed vector, using the
    /// level's solution and residual as scratch.
    fn largest_eigenvalue(&mut self) -> f64 {
        for (p, x) in self.solution.iter_mut().enumerate() {
            let t = p as f64;
            *x = Vec3::new(
                T::from_f64((0.7315 * t).sin()),
                T::from_f64((0.5127 * t + 1.0).sin()),
                T::from_f64((0.3119 * t + 2.0).sin()),
            );
        }
        let mut lambda = 1.0;
        let mut norm = norm_of(&self.solution);
        for _ in 0..POWER_ITERATIONS {
            self.operator.apply(&self.solution, &mut self.residual);
            for ((x, r), inverse) in self.solution.iter_mut().zip(&self.residual).zip(&self.inverse_diagonal)
            {
                *x = inverse.apply(*r);
            }
            let next = norm_of(&self.solution);
            if !(next > 0.0 && next.is_finite() && norm > 0.0) {
                return 1.0;
            }
            lambda = next / norm;
            let scale = T::from_f64(1.0 / next);
            for x in &mut self.solution {
                *x *= scale;
            }
            norm = 1.0;
        }
        lambda
    }

    /// One block Gauss-Seidel sweep on `A solution = rhs`, forward or backward.
    fn sweep(&mut self, backward: bool) {
        let n = self.operator.rows();
        for k in 0..n {
            let p = if backward { n - 1 - k } else { k };
            let mut r = self.rhs[p];
            for e in self.operator.row(p) {
                r -= self.operator.blocks[e].apply(self.solution[self.operator.column(e)]);
            }
            let correction = self.inverse_diagonal[p].apply(r);
            self.solution[p] += correction;
        }
    }

    fn update_residual(&mut self) {
        self.operator.apply(&self.solution, &mut self.residual);
        for (r, &b) in self.residual.iter_mut().zip(&self.rhs) {
            *r = b - *r;
        }
    }
}

fn norm_of<T: Real>(x: &[Vec3<T>]) -> f64 {
    x.iter().map(|v| v.to_dvec3().length_squared()).sum::<f64>().sqrt()
}

impl<T: Real> Transfer<T> {
    /// The transfer from a level with operator pattern `fine` whose particles are grouped as
    /// `aggregate` (`NONE` for a held one) into `aggregates` aggregates, and the coarse
    /// operator's pattern.
    fn new(fine: &BlockCsr<T>, aggregate: &[u32], aggregates: usize) -> (Self, BlockCsr<T>) {
        let n = fine.rows();
        let mut sizes = vec![0usize; aggregates];
        for &a in aggregate.iter().filter(|&&a| a != NONE) {
            sizes[a as usize] += 1;
        }
        let tentative = aggregate
            .iter()
            .map(|&a| if a == NONE { T::ZERO } else { T::from_f64(1.0 / (sizes[a as usize] as f64).sqrt()) })
            .collect();
        let rows = (0..n)
            .map(|p| {
                fine.row_columns(p).iter().map(|&q| aggregate[q as usize]).filter(|&a| a != NONE).collect()
            })
            .collect();
        let prolongator = BlockCsr::from_rows(aggregates, rows);
        let smoothing_slots = (0..n)
            .flat_map(|p| fine.row(p).map(move |e| (p, e)))
            .map(|(p, e)| match aggregate[fine.column(e)] {
                NONE => NONE,
                a => prolongator.slot(p, a as usize).expect("planned") as u32,
            })
            .collect();
        let own = (0..n)
            .map(|p| match aggregate[p] {
                NONE => NONE,
                a => prolongator.slot(p, a as usize).expect("planned") as u32,
            })
            .collect();
        let product_rows = (0..n)
            .map(|p| {
                fine.row_columns(p)
                    .iter()
                    .flat_map(|&q| prolongator.row_columns(q as usize).iter().copied())
                    .collect()
            })
            .collect();
        let product = BlockCsr::from_rows(aggregates, product_rows);
        let mut product_slots = Vec::new();
        for p in 0..n {
            for &q in fine.row_columns(p) {
                for &a in prolongator.row_columns(q as usize) {
                    product_slots.push(product.slot(p, a as usize).expect("planned") as u32);
                }
            }
        }
        let mut coarse_rows = vec![Vec::new(); aggregates];
        for p in 0..n {
            for &a in prolongator.row_columns(p) {
                coarse_rows[a as usize].extend_from_slice(product.row_columns(p));
            }
        }
        let coarse = BlockCsr::from_rows(aggregates, coarse_rows);
        let mut galerkin_slots = Vec::new();
        for p in 0..n {
            for &a in prolongator.row_columns(p) {
                for &b in product.row_columns(p) {
                    galerkin_slots.push(coarse.slot(a as usize, b as usize).expect("planned") as u32);
                }
            }
        }
        let transfer = Self {
            tentative,
            own,
            omega: T::ZERO,
            prolongator,
            smoothing_slots,
            product,
            product_slots,
            galerkin_slots,
        };
        (transfer, coarse)
    }

    /// Smooths the prolongator with the fine level's operator and damping `omega`, and fills
    /// `coarse` with `Pᵀ A P`; gives up part-way as soon as `interrupt` is raised.
    fn refill(
        &mut self,
        fine: &Level<T>,
        omega: T,
        coarse: &mut BlockCsr<T>,
        interrupt: Option<&Interrupt>,
    ) -> Result<(), Interrupted> {
        self.omega = omega;
        let a = &fine.operator;
        let p = &mut self.prolongator;
        p.clear();
        for row in 0..a.rows() {
            look(row, interrupt)?;
            for e in a.row(row) {
                let slot = self.smoothing_slots[e];
                if slot != NONE {
                    p.blocks[slot as usize].add_scaled(self.tentative[a.column(e)], &a.blocks[e]);
                }
            }
            let scale = -omega;
            for f in p.row(row) {
                p.blocks[f] = fine.inverse_diagonal[row].times(&p.blocks[f]).scaled(scale);
            }
            if self.own[row] != NONE {
                let own = &mut p.blocks[self.own[row] as usize];
                own.add_scaled(T::ONE, &Block::diagonal(self.tentative[row]));
            }
        }
        let p = &self.prolongator;
        self.product.clear();
        let mut k = 0;
        for row in 0..a.rows() {
            look(row, interrupt)?;
            for e in a.row(row) {
                for f in p.row(a.column(e)) {
                    self.product.blocks[self.product_slots[k] as usize].add_mul(&a.blocks[e], &p.blocks[f]);
                    k += 1;
                }
            }
        }
        coarse.clear();
        let mut k = 0;
        for row in 0..a.rows() {
            look(row, interrupt)?;
            for f in p.row(row) {
                for g in self.product.row(row) {
                    coarse.blocks[self.galerkin_slots[k] as usize]
                        .add_transpose_mul(&p.blocks[f], &self.product.blocks[g]);
                    k += 1;
                }
            }
        }
        Ok(())
    }
}

/// Sums the weights of repeated neighbours and sorts by neighbour.
fn merge_duplicates(neighbours: &mut Vec<(u32, f64)>) {
    neighbours.sort_by_key(|&(q, _)| q);
    neighbours.dedup_by(|later, kept| {
        if later.0 == kept.0 {
            kept.1 += later.1;
            true
        } else {
            false
        }
    });
}

/// Groups the `included` particles of `graph` into aggregates (Vaněk's three passes): roots
/// whose strong neighbours are all free take them; the rest join the aggregate of their strongest
/// strong neighbour placed by the first pass; what remains forms aggregates with its free strong
/// neighbours. Returns each particle's aggregate (`NONE` when not included) and the count.
fn aggregate(graph: &Graph, included: &[bool]) -> (Vec<u32>, usize) {
    let n = graph.len();
    let stiffest: Vec<f64> =
        graph.iter().map(|edges| edges.iter().map(|&(_, w)| w).fold(0.0, f64::max)).collect();
    let strong: Vec<Vec<(u32, f64)>> = (0..n)
        .map(|p| {
            graph[p]
                .iter()
                .copied()
                .filter(|&(q, w)| {
                    let q = q as usize;
                    included[q] && w > 0.0 && w >= STRENGTH * stiffest[p].max(stiffest[q])
                })
                .collect()
        })
        .collect();
    let mut aggregate = vec![NONE; n];
    let mut count = 0u32;
    for p in 0..n {
        if included[p]
            && aggregate[p] == NONE
            && strong[p].iter().all(|&(q, _)| aggregate[q as usize] == NONE)
        {
            aggregate[p] = count;
            for &(q, _) in &strong[p] {
                aggregate[q as usize] = count;
            }
            count += 1;
        }
    }
    let first = aggregate.clone();
    for p in 0..n {
        if !included[p] || aggregate[p] != NONE {
            continue;
        }
        let mut best: Option<(u32, f64)> = None;
        for &(q, w) in &strong[p] {
            let a = first[q as usize];
            if a != NONE && best.is_none_or(|(_, b)| w > b) {
                best = Some((a, w));
            }
        }
        if let Some((a, _)) = best {
            aggregate[p] = a;
        }
    }
    for p in 0..n {
        if included[p] && aggregate[p] == NONE {
            aggregate[p] = count;
            for &(q, _) in &strong[p] {
                if aggregate[q as usize] == NONE {
                    aggregate[q as usize] = count;
                }
            }
            count += 1;
        }
    }
    (aggregate, count as usize)
}

/// The graph between aggregates: the summed stiffness of every spring joining two.
fn coarse_graph(graph: &Graph, aggregate: &[u32], aggregates: usize) -> Graph {
    let mut coarse: Graph = vec![Vec::new(); aggregates];
    for (p, edges) in graph.iter().enumerate() {
        let a = aggregate[p];
        if a == NONE {
            continue;
        }
        for &(q, w) in edges {
            let b = aggregate[q as usize];
            if b != NONE && b != a {
                coarse[a as usize].push((b, w));
            }
        }
    }
    for edges in &mut coarse {
        merge_duplicates(edges);
    }
    coarse
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solver::bodies::Mesh;
    use crate::solver::fabric::Fabric;
    use crate::solver::forces::dynamics::Dynamics;
    use crate::solver::forces::springs::{direction, stiffness_block};
    use crate::solver::model::{Model, SpringParams};

    const H: f64 = 1.0 / 60.0;

    /// An `n × n`-vertex fabric sheet of 1 m², two corners pinned, crumpled so that its springs
    /// point every way and some are compressed.
    fn crumpled_fabric(n: usize) -> (Model, Vec<Vec3<f64>>) {
        let mut vertices = Vec::new();
        for j in 0..n {
            for i in 0..n {
                vertices.push(DVec3::new(i as f64 / (n - 1) as f64, 0.0, j as f64 / (n - 1) as f64));
            }
        }
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = j * n + i;
                triangles.extend([[a, a + n, a + 1], [a + 1, a + n, a + n + 1]]);
            }
        }
        let springs = SpringParams { stiffness: 0.0, damping: 0.0 };
        let mesh = Mesh {
            vertices,
            triangles,
            mass: 0.5,
            velocity: DVec3::ZERO,
            structural: springs,
            bending: springs,
            pins: vec![0, n - 1],
        };
        let fabric =
            Fabric { density: 0.2, stretch: 2000.0, shear: 500.0, bending: 1e-3, damping_time: 1e-3 };
        let mut model = Model::default();
        model.add_fabric_mesh(&mesh, &fabric);
        let positions = model
            .positions
            .iter()
            .enumerate()
            .map(|(p, x)| {
                let t = p as f64;
                let bump =
                    DVec3::new(0.03 * (1.3 * t).sin(), 0.2 * (3.0 * x.x).sin() * x.z, 0.02 * (0.7 * t).cos());
                Vec3::from_dvec3(*x * 0.9 + bump)
            })
            .collect();
        (model, positions)
    }

    /// The step's blocks at `positions` as the spring-list solver makes them.
    fn spring_blocks(dynamics: &Dynamics<f64>, positions: &[Vec3<f64>]) -> Vec<Sym3<f64>> {
        dynamics
            .springs
            .iter()
            .map(|s| {
                let Some((n, l)) = direction(positions[s.j as usize] - positions[s.i as usize]) else {
                    return Sym3::ZERO;
                };
                Sym3::outer(n) * (H * s.damping) + stiffness_block(s, n, l) * (H * H)
            })
            .collect()
    }

    /// A hierarchy of the crumpled sheet refilled for a step, with the system's parts.
    fn refilled(n: usize, filter: Option<&[Sym3<f64>]>) -> (Aggregation<f64>, Dynamics<f64>, Vec<Sym3<f64>>) {
        let (model, positions) = crumpled_fabric(n);
        let dynamics = Dynamics::<f64>::new(&model, DVec3::new(0.0, -9.81, 0.0), 0.0);
        let held: Vec<bool> = dynamics.inverse_masses.iter().map(|&w| w == 0.0).collect();
        let mut aggregation = Aggregation::with_depth(
            held.len(),
            &dynamics.springs,
            dynamics.bending.as_ref(),
            &held,
            usize::MAX,
        );
        let blocks = spring_blocks(&dynamics, &positions);
        let system = FineSystem {
            held_blocks: &[],
            mass_diagonal: &dynamics.masses,
            spring_blocks: &blocks,
            bending: dynamics.bending.as_ref().map(|hinges| (hinges, H * H, H)),
        };
        aggregation.refill(&system, filter, None).expect("nothing interrupts it");
        (aggregation, dynamics, blocks)
    }

    /// Per particle: a projection onto the plane across a direction that turns from particle to
    /// particle on every third one, the identity on the others.
    fn contact_filter(particles: usize) -> Vec<Sym3<f64>> {
        (0..particles)
            .map(|p| {
                if p % 3 != 0 {
                    return Sym3::identity();
                }
                let t = p as f64;
                let n = DVec3::new((0.4 * t).sin(), 1.0, (0.9 * t).cos()).normalize();
                let outer = Sym3::outer(Vec3::<f64>::from_dvec3(n)).entries();
                let identity = Sym3::<f64>::identity().entries();
                Sym3::from_entries(std::array::from_fn(|k| identity[k] - outer[k]))
            })
            .collect()
    }

    fn dense_product(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let columns = b[0].len();
        a.iter()
            .map(|row| (0..columns).map(|c| row.iter().zip(b).map(|(x, b_row)| x * b_row[c]).sum()).collect())
            .collect()
    }

    fn transpose(a: &[Vec<f64>]) -> Vec<Vec<f64>> {
        (0..a[0].len()).map(|c| a.iter().map(|row| row[c]).collect()).collect()
    }

    fn largest(a: &[Vec<f64>]) -> f64 {
        a.iter().flatten().fold(0.0, |m, &x| m.max(x.abs()))
    }

    /// The dense system `F (S A S + I − S) F + I − F` of the step, from the spring list: `F`
    /// keeps the free particles, `S` is the filter (the identity without one).
    fn dense_system(
        dynamics: &Dynamics<f64>,
        blocks: &[Sym3<f64>],
        filter: Option<&[Sym3<f64>]>,
    ) -> Vec<Vec<f64>> {
        let n = dynamics.masses.len();
        let mut a = vec![vec![0.0; 3 * n]; 3 * n];
        let mut add = |p: usize, q: usize, block: [[f64; 3]; 3]| {
            for r in 0..3 {
                for c in 0..3 {
                    a[3 * p + r][3 * q + c] += block[r][c];
                }
            }
        };
        for (p, &m) in dynamics.masses.iter().enumerate() {
            add(p, p, Block::diagonal(m).0);
        }
        for (s, block) in dynamics.springs.iter().zip(blocks) {
            let (i, j, b) = (s.i as usize, s.j as usize, Block::from_sym(block));
            add(i, i, b.0);
            add(j, j, b.0);
            add(i, j, b.scaled(-1.0).0);
            add(j, i, b.scaled(-1.0).0);
        }
        if let Some(hinges) = &dynamics.bending {
            hinges.for_each_entry(|p, q, c, d| add(p, q, Block::diagonal(H * H * c + H * d).0));
        }
        let mut projection = vec![vec![0.0; 3 * n]; 3 * n];
        for p in 0..n {
            let s = match filter {
                Some(filter) => Block::from_sym(&filter[p]),
                None => Block::identity(),
            };
            let free = if dynamics.inverse_masses[p] > 0.0 { 1.0 } else { 0.0 };
            for r in 0..3 {
                for c in 0..3 {
                    projection[3 * p + r][3 * p + c] = free * s.0[r][c];
                }
            }
        }
        let mut filtered = dense_product(&projection, &dense_product(&a, &projection));
        for (u, row) in filtered.iter_mut().enumerate() {
            for (w, value) in row.iter_mut().enumerate() {
                *value += if u == w { 1.0 } else { 0.0 } - projection[u][w];
            }
        }
        filtered
    }

    fn check_galerkin(filter: Option<&[Sym3<f64>]>) {
        let (aggregation, dynamics, blocks) = refilled(16, filter);
        assert!(aggregation.depth() >= 2, "the sheet is coarsened");
        let fine = aggregation.levels[0].operator.to_dense();
        let expected = dense_system(&dynamics, &blocks, filter);
        let scale = largest(&expected);
        for (row, expected_row) in fine.iter().zip(&expected) {
            for (&value, &expected) in row.iter().zip(expected_row) {
                assert!((value - expected).abs() <= 1e-14 * scale, "{value} against {expected}");
            }
        }
        for l in 0..aggregation.depth() - 1 {
            let a = aggregation.levels[l].operator.to_dense();
            let p = aggregation.transfers[l].prolongator.to_dense();
            let galerkin = dense_product(&transpose(&p), &dense_product(&a, &p));
            let coarse = aggregation.levels[l + 1].operator.to_dense();
            let scale = largest(&galerkin);
            for (row, expected_row) in coarse.iter().zip(&galerkin) {
                for (&value, &expected) in row.iter().zip(expected_row) {
                    assert!(
                        (value - expected).abs() <= 1e-12 * scale,
                        "level {l}: {value} against {expected}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_coarse_levels_are_the_galerkin_products_of_the_step_system() {
        check_galerkin(None);
    }

    #[test]
    fn a_filtered_system_is_coarsened_as_its_galerkin_products() {
        check_galerkin(Some(&contact_filter(256)));
    }

    /// Every free particle is in one aggregate and no pinned one is; the tentative prolongator's
    /// columns are orthonormal; the prolongator is it smoothed by one damped Jacobi step,
    /// `(I − ω D⁻¹ A) P₀`, with `ω λ = 4/3` below 2 for the `λ` the power iteration finds.
    #[test]
    fn the_prolongator_is_the_smoothed_translations_of_the_aggregates() {
        let (aggregation, dynamics, _) = refilled(16, None);
        let transfer = &aggregation.transfers[0];
        let coarse = aggregation.levels[1].operator.rows();
        let n = dynamics.masses.len();
        let mut tentative = vec![vec![0.0; 3 * coarse]; 3 * n];
        let mut column_norms = vec![0.0; coarse];
        for p in 0..n {
            let own = transfer.own[p];
            assert_eq!(own == NONE, dynamics.inverse_masses[p] == 0.0, "particle {p}");
            if own != NONE {
                let a = transfer.prolongator.column(own as usize);
                column_norms[a] += transfer.tentative[p] * transfer.tentative[p];
                for axis in 0..3 {
                    tentative[3 * p + axis][3 * a + axis] = transfer.tentative[p];
                }
            }
        }
        assert!(column_norms.iter().all(|&c| (c - 1.0).abs() < 1e-14), "{column_norms:?}");
        let a = aggregation.levels[0].operator.to_dense();
        let mut inverse_diagonal = vec![vec![0.0; 3 * n]; 3 * n];
        for (p, inverse) in aggregation.levels[0].inverse_diagonal.iter().enumerate() {
            for r in 0..3 {
                for c in 0..3 {
                    inverse_diagonal[3 * p + r][3 * p + c] = inverse.0[r][c];
                }
            }
        }
        let smoothing = dense_product(&inverse_diagonal, &dense_product(&a, &tentative));
        let omega = transfer.omega;
        assert!(omega > 0.0 && omega < 1.0, "ω = {omega}");
        let p = transfer.prolongator.to_dense();
        for ((row, t_row), s_row) in p.iter().zip(&tentative).zip(&smoothing) {
            for ((&value, &t), &s) in row.iter().zip(t_row).zip(s_row) {
                assert!((value - (t - omega * s)).abs() < 1e-13, "{value} against {}", t - omega * s);
            }
        }
    }

    /// Two sheets side by side make two components of the graph, which share no aggregate on
    /// any level.
    #[test]
    fn separate_bodies_share_no_aggregate() {
        let (mut model, _) = crumpled_fabric(12);
        let first = model.particle_count();
        let (other, _) = crumpled_fabric(12);
        let springs = SpringParams { stiffness: 1000.0, damping: 1.0 };
        let mesh = Mesh {
            vertices: other.positions.iter().map(|x| *x + DVec3::new(3.0, 0.0, 0.0)).collect(),
            triangles: other.triangles.iter().map(|t| t.map(|v| v as usize)).collect(),
            mass: 0.5,
            velocity: DVec3::ZERO,
            structural: springs,
            bending: springs,
            pins: vec![],
        };
        model.add_mesh(&mesh);
        let dynamics = Dynamics::<f64>::new(&model, DVec3::ZERO, 0.0);
        let held: Vec<bool> = dynamics.inverse_masses.iter().map(|&w| w == 0.0).collect();
        let aggregation = Aggregation::with_depth(
            held.len(),
            &dynamics.springs,
            dynamics.bending.as_ref(),
            &held,
            usize::MAX,
        );
        assert!(aggregation.depth() >= 2);
        // Each particle's body, carried down the levels through its own aggregate.
        let mut body: Vec<Option<bool>> = (0..held.len()).map(|p| (!held[p]).then_some(p >= first)).collect();
        for transfer in &aggregation.transfers {
            let mut coarse = vec![None; transfer.prolongator.columns()];
            for (p, &own) in transfer.own.iter().enumerate() {
                if own == NONE {
                    continue;
                }
                let a = transfer.prolongator.column(own as usize);
                assert!(coarse[a].is_none() || coarse[a] == body[p], "aggregate {a} spans both bodies");
                coarse[a] = body[p];
            }
            assert!(coarse.iter().all(Option::is_some));
            body = coarse;
        }
    }

    fn dot(a: &[Vec3<f64>], b: &[Vec3<f64>]) -> f64 {
        a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum()
    }

    fn check_symmetric(filter: Option<&[Sym3<f64>]>) {
        let (mut aggregation, dynamics, _) = refilled(24, filter);
        assert!(aggregation.depth() >= 3);
        let n = dynamics.masses.len();
        let free = |p: usize| if dynamics.inverse_masses[p] > 0.0 { 1.0 } else { 0.0 };
        let x: Vec<_> = (0..n)
            .map(|p| Vec3::new((0.3 * p as f64).sin(), (1.1 * p as f64).cos(), 0.5) * free(p))
            .collect();
        let y: Vec<_> = (0..n)
            .map(|p| Vec3::new((0.17 * p as f64).cos(), -1.0, (2.3 * p as f64).sin()) * free(p))
            .collect();
        let (mut mx, mut my) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        aggregation.apply(&x, &mut mx);
        aggregation.apply(&y, &mut my);
        let (left, right) = (dot(&mx, &y), dot(&x, &my));
        let scale = dot(&mx, &mx).sqrt() * dot(&y, &y).sqrt();
        assert!((left - right).abs() <= 1e-12 * scale, "⟨M⁻¹x, y⟩ = {left}, ⟨x, M⁻¹y⟩ = {right}");
        assert!(dot(&mx, &x) > 0.0 && dot(&my, &y) > 0.0);
        for p in (0..n).filter(|&p| free(p) == 0.0) {
            assert_eq!(mx[p], Vec3::ZERO, "a pinned particle gets no correction");
        }
    }

    /// A refill given up when the interrupt is raised, part-way through its products, leaves
    /// nothing behind: the next refill gives the same V-cycle, bit for bit, as a hierarchy never
    /// interrupted.
    #[test]
    fn a_refill_given_up_leaves_nothing_behind() {
        let (mut whole, dynamics, blocks) = refilled(24, None);
        let (mut interrupted, ..) = refilled(24, Some(&contact_filter(576)));
        let system = FineSystem {
            held_blocks: &[],
            mass_diagonal: &dynamics.masses,
            spring_blocks: &blocks,
            bending: dynamics.bending.as_ref().map(|hinges| (hinges, H * H, H)),
        };
        let raised = Interrupt::new();
        raised.raise();
        assert_eq!(interrupted.refill(&system, None, Some(&raised)), Err(Interrupted));
        interrupted.refill(&system, None, Some(&Interrupt::new())).expect("not raised");
        let n = dynamics.masses.len();
        let r: Vec<_> =
            (0..n).map(|p| Vec3::new((0.3 * p as f64).sin(), 1.0, (1.7 * p as f64).cos())).collect();
        let (mut z_whole, mut z_interrupted) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        whole.apply(&r, &mut z_whole);
        interrupted.apply(&r, &mut z_interrupted);
        assert!(z_whole.iter().any(|z| *z != Vec3::ZERO));
        assert_eq!(z_whole, z_interrupted);
    }

    #[test]
    fn the_v_cycle_is_symmetric_and_positive() {
        check_symmetric(None);
    }

    #[test]
    fn the_v_cycle_of_a_filtered_system_is_symmetric_and_positive() {
        check_symmetric(Some(&contact_filter(576)));
    }
}
