//! The one multigrid hierarchy of the crate: how coarse levels are built
//! ([`Hierarchy::build`]) and the V-cycle over them ([`Hierarchy::cycle`]),
//! generic over the levels. Used by the depth solve's Gauss-Newton systems
//! (`solver::multigrid`: vertex-centred bilinear interpolation, Galerkin
//! 5x5 stencils, band red-black Gauss-Seidel) and the albedo integration
//! (`crate::albedo`: 2x2-block piecewise-constant Galerkin levels, damped
//! Jacobi, the cycle as a conjugate-gradient preconditioner).
//!
//! A problem supplies its levels ([`Level`]: smoothing, the restriction of
//! the residual, the prolongation of a correction) and how a level yields
//! the next coarser one ([`Coarsen`], which also says when a level is the
//! coarsest). The finest level may be of another type than the coarse ones
//! (the depth solve's is the Gauss-Newton system with its SOR smoother,
//! solved from its current unknowns). Uses nothing.

/// One level of a hierarchy: a linear system `A x = b` with its unknowns,
/// right-hand side and the transfers to the next coarser level.
pub(crate) trait Level {
    /// The type of the coarser levels (all of one type).
    type Coarse: Level<Coarse = Self::Coarse>;

    /// Runs `sweeps` smoothing sweeps on this level's unknowns.
    fn smooth(&mut self, sweeps: usize);

    /// Sets `coarse`'s right-hand side to the restriction of this level's
    /// residual `b - A x`.
    fn restrict_residual(&mut self, coarse: &mut Self::Coarse);

    /// Adds the prolongation of `coarse`'s unknowns (the coarse correction)
    /// to this level's unknowns.
    fn prolong_add(&mut self, coarse: &Self::Coarse);

    /// Sets this level's unknowns to zero.
    fn zero_unknowns(&mut self);
}

/// A level that yields its coarser level (in both problems the Galerkin
/// operator `P^T A P` of its own transfers).
pub(crate) trait Coarsen {
    /// The type of the coarser levels.
    type Coarse: Coarsen<Coarse = Self::Coarse>;

    /// The next coarser level, or None when this level is the coarsest
    /// (the problem's own rule).
    fn coarsen(&self) -> Option<Self::Coarse>;
}

/// Smoothing sweeps of a V-cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Sweeps {
    /// Sweeps before and after each coarse correction.
    pub smoothing: usize,
    /// Sweeps on the coarsest level, which is solved by smoothing alone.
    pub coarsest: usize,
}

/// The coarse levels below one finest level, the finest-but-one first.
pub(crate) struct Hierarchy<L> {
    levels: Vec<L>,
}

impl<L> Hierarchy<L>
where
    L: Level<Coarse = L> + Coarsen<Coarse = L>,
{
    /// Coarsens `fine` until a level is the coarsest (no coarse level when
    /// `fine` itself is).
    pub(crate) fn build<F: Coarsen<Coarse = L>>(fine: &F) -> Self {
        let mut levels = Vec::new();
        let mut next = fine.coarsen();
        while let Some(level) = next {
            next = level.coarsen();
            levels.push(level);
        }
        Self { levels }
    }

    /// The coarse levels, the finest of them first.
    pub(crate) fn levels(&self) -> &[L] {
        &self.levels
    }

    /// One V-cycle on `fine` from its current unknowns: smooth, restrict
    /// the residual, the same cycle on the coarser levels from zero,
    /// prolong its correction, smooth. With no coarse level, `fine` is
    /// the coarsest and smoothed `sweeps.coarsest` times.
    pub(crate) fn cycle<F: Level<Coarse = L>>(&mut self, fine: &mut F, sweeps: Sweeps) {
        v_cycle(fine, &mut self.levels, sweeps);
    }
}

/// [`Hierarchy::cycle`] on `level` above `coarser`.
fn v_cycle<F: Level>(level: &mut F, coarser: &mut [F::Coarse], sweeps: Sweeps) {
    let Some((next, rest)) = coarser.split_first_mut() else {
        level.smooth(sweeps.coarsest);
        return;
    };
    level.smooth(sweeps.smoothing);
    level.restrict_residual(next);
    next.zero_unknowns();
    v_cycle(next, rest, sweeps);
    level.prolong_add(next);
    level.smooth(sweeps.smoothing);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1-D Poisson problem `-x'' = b` (Dirichlet ends) on `n` interior
    /// points: vertex-centred linear interpolation, Galerkin coarse
    /// operators (the same 3-point stencil scaled by 1/2 per level),
    /// weighted Jacobi.
    struct Line {
        /// The stencil's diagonal `2 s` and off-diagonals `-s`.
        scale: f64,
        x: Vec<f64>,
        b: Vec<f64>,
    }

    impl Line {
        fn new(n: usize, scale: f64) -> Self {
            Self {
                scale,
                x: vec![0.0; n],
                b: vec![0.0; n],
            }
        }

        fn residual(&self) -> Vec<f64> {
            let n = self.x.len();
            (0..n)
                .map(|i| {
                    let left = if i > 0 { self.x[i - 1] } else { 0.0 };
                    let right = if i + 1 < n { self.x[i + 1] } else { 0.0 };
                    self.b[i] - self.scale * (2.0 * self.x[i] - left - right)
                })
                .collect()
        }
    }

    impl Level for Line {
        type Coarse = Line;

        fn smooth(&mut self, sweeps: usize) {
            for _ in 0..sweeps {
                let r = self.residual();
                for (x, r) in self.x.iter_mut().zip(r) {
                    *x += 2.0 / 3.0 * r / (2.0 * self.scale);
                }
            }
        }

        fn restrict_residual(&mut self, coarse: &mut Line) {
            let r = self.residual();
            for (i, b) in coarse.b.iter_mut().enumerate() {
                *b = 0.5 * r[2 * i] + r[2 * i + 1] + 0.5 * r[2 * i + 2];
            }
        }

        fn prolong_add(&mut self, coarse: &Line) {
            for (i, &y) in coarse.x.iter().enumerate() {
                self.x[2 * i] += 0.5 * y;
                self.x[2 * i + 1] += y;
                self.x[2 * i + 2] += 0.5 * y;
            }
        }

        fn zero_unknowns(&mut self) {
            self.x.iter_mut().for_each(|x| *x = 0.0);
        }
    }

    impl Coarsen for Line {
        type Coarse = Line;

        fn coarsen(&self) -> Option<Line> {
            let n = self.x.len();
            (n >= 7).then(|| Line::new((n - 1) / 2, 0.5 * self.scale))
        }
    }

    fn norm(v: &[f64]) -> f64 {
        v.iter().map(|v| v * v).sum::<f64>().sqrt()
    }

    #[test]
    fn the_levels_stop_at_the_coarsest_rule() {
        let fine = Line::new(127, 1.0);
        let hierarchy = Hierarchy::build(&fine);
        let sizes: Vec<usize> = hierarchy.levels().iter().map(|l| l.x.len()).collect();
        assert_eq!(sizes, [63, 31, 15, 7, 3]);
        assert!(
            Hierarchy::<Line>::build(&Line::new(5, 1.0))
                .levels()
                .is_empty()
        );
    }

    #[test]
    fn v_cycles_solve_a_poisson_line_at_a_rate_independent_of_its_size() {
        for n in [63, 255] {
            let mut fine = Line::new(n, 1.0);
            fine.b = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
            let mut hierarchy = Hierarchy::build(&fine);
            let sweeps = Sweeps {
                smoothing: 2,
                coarsest: 50,
            };
            let r0 = norm(&fine.residual());
            for _ in 0..8 {
                hierarchy.cycle(&mut fine, sweeps);
            }
            // Jacobi alone would leave most of the smooth error: the
            // cycles' factor is about 0.1 per cycle at any size.
            let reduction = norm(&fine.residual()) / r0;
            assert!(reduction < 1e-5, "n {n}: reduced to {reduction}");
        }
    }

    #[test]
    fn with_no_coarse_level_a_cycle_is_the_coarsest_smoothing() {
        let mut cycled = Line::new(5, 1.0);
        cycled.b = vec![1.0, -2.0, 3.0, 0.5, 1.5];
        let mut smoothed = Line::new(5, 1.0);
        smoothed.b = cycled.b.clone();
        let mut hierarchy = Hierarchy::build(&cycled);
        let sweeps = Sweeps {
            smoothing: 2,
            coarsest: 9,
        };
        hierarchy.cycle(&mut cycled, sweeps);
        smoothed.smooth(9);
        assert_eq!(cycled.x, smoothed.x);
    }
}
