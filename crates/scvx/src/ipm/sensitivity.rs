//! The last solution moved to a nearby right-hand side by one Newton step on the last
//! factorization (no new factorization, no iterations).

use super::*;

impl InteriorPoint {
    /// The primal solution of the problem last solved with its right-hand side moved from
    /// `b` to `b_new` (P, q and A unchanged), to first order: one Newton step from the last
    /// solution, on the KKT factorization of its last iteration,
    ///
    /// ```text
    /// PΔx + AᵀΔz = 0,   AΔx + Δs = b_new − b,   WΔz + W⁻¹Δs = 0 (cone rows),
    /// ```
    ///
    /// refined against the full system as a corrector direction is. Where the active set
    /// holds this is the derivative of the solution with respect to b: a row at its bound
    /// (s ≪ z, W⁻² large) keeps its value of `Ax − b`, a slack one (s ≫ z) takes the change
    /// in its slack. With equality and nonnegative rows the move is exact to second order in
    /// `b_new − b`; a second-order cone active at the solution (s and z both on its
    /// boundary) is followed only approximately (the scaling of the last iterate does not
    /// carry the boundary's curvature exactly: on random problems such moves land 5–30 % of
    /// the move away from the moved problem's solution). This is how an interior-point SQP
    /// computes a second-order correction (IPOPT reuses the step's factorization the same
    /// way); unlike a solve, the point need not respect the cones of rows that become active.
    ///
    /// `None` before a solved problem, after one solved without an iteration (its
    /// factorization is another problem's), or when a value is not finite. The solver's own
    /// iterate (and so the next warm start) is left as it was.
    ///
    /// # Panics
    /// If a slice length differs from the pattern's.
    pub fn moved_solution(&mut self, p: &[f64], b: &[f64], b_new: &[f64]) -> Option<&[f64]> {
        assert_eq!(p.len(), self.p_rowval.len(), "P values");
        assert_eq!(b.len(), self.m, "b");
        assert_eq!(b_new.len(), self.m, "b_new");
        if !self.has_solution || self.iterations == 0 {
            return None;
        }
        self.rx.fill(0.0);
        for ((r, new), old) in self.rz.iter_mut().zip(b_new).zip(b) {
            *r = old - new;
        }
        self.u.fill(0.0);
        self.direction(p, true);
        for ((m, x), d) in self.x_moved.iter_mut().zip(&self.x).zip(&self.dx) {
            *m = x + d;
        }
        self.x_moved.iter().all(|x| x.is_finite()).then_some(&self.x_moved[..])
    }
}
