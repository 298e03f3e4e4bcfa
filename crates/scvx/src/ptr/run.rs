//! Driving a solve: start from a guess, step, observe, and collect the result.

use super::*;

/// Iteration records reserved when a solve starts (more grow the history as needed).
const MAX_HISTORY_RESERVE: usize = 1024;

impl Ptr {
    /// Runs PTR from the guess `(x, u, s)` (N×n, N×m, N) to the end: [`start`](Self::start),
    /// then [`step`](Self::step) until a step reports a final status.
    ///
    /// # Errors
    /// Unusable settings, guesses of the wrong size or not finite, a dynamics evaluation
    /// error. Solver outcomes (not converged, infeasible subproblem) are data in the result.
    pub fn solve(&mut self, x: &[f64], u: &[f64], s: &[f64]) -> Result<PtrResult, PtrError> {
        self.solve_with(x, u, s, |_, _| {})
    }

    /// Like [`solve`](Self::solve), calling `observer` after every iteration with its record
    /// and the current reference trajectory (the last accepted one): the hook through which
    /// progress is printed ([`IterationTable`]) or streamed.
    ///
    /// # Errors
    /// As [`solve`](Self::solve).
    pub fn solve_with(
        &mut self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        mut observer: impl FnMut(&Iteration, &Trajectory<'_>),
    ) -> Result<PtrResult, PtrError> {
        self.start(x, u, s)?;
        loop {
            let it = self.step()?;
            if let Some(t) = self.trajectory() {
                observer(&it, &t);
            }
            if it.status.is_some() {
                break;
            }
        }
        self.result().ok_or(PtrError::NotRunning)
    }

    /// Sets the reference to the guess `(x, u, s)` (N×n, N×m, N), discretizes it and resets
    /// the weights and the history; [`step`](Self::step) then iterates. Reuses every buffer
    /// (and the subproblem solver) of an earlier solve of this `Ptr`.
    ///
    /// # Errors
    /// As [`solve`](Self::solve).
    pub fn start(&mut self, x: &[f64], u: &[f64], s: &[f64]) -> Result<(), PtrError> {
        self.check_trajectory(x, u, s)?;
        let mut st = match self.state.take() {
            Some(st) => st,
            None => Box::new(self.iterate()),
        };
        st.timings = Timings::default();
        // A guess whose discretization fails leaves no solve running (step: NotRunning).
        self.set_reference(&mut st, x, u, s)?;
        st.lam_vc.fill(self.settings.lam_vc);
        st.lam_vb.fill(self.settings.lam_vb);
        st.lam_tr = self.settings.lam_tr;
        self.apply_starting_prices(&mut st);
        self.cost_on = true;
        // A new solve does not warm-start from the last one's subproblem.
        if let Some(native) = st.native.as_mut() {
            native.restart();
        }
        // Nor solve with the last one's Clarabel: updated in place, it does not reproduce a
        // new solver's result to the last bit, and a fallback to it then made a second solve
        // of the same problem walk elsewhere (the UR5e rigid-body task: 31 and 30 iterations).
        st.clarabel = None;
        // Nor from its multipliers (the exact curvature and the Lagrangian merit read them).
        st.duals.fill(0.0);
        st.history.clear();
        // Room for a typical solve; a huge cap must not reserve its whole history up front.
        st.history.reserve(self.settings.max_iterations.min(MAX_HISTORY_RESERVE));
        st.status = None;
        let prices = (&st.lam_vc[..], &st.lam_vb[..]);
        (st.jbar, st.tf, _, _) =
            self.merit(x, u, s, &st.dbar, &mut st.ev, prices, GridAt::Reference);
        self.state = Some(st);
        Ok(())
    }

    /// One PTR iteration: linearize at the reference, solve the convex subproblem, accept or
    /// reject the candidate, update the weights. The record's `status` is set on the final
    /// iteration (converged, iteration cap, stalled, subproblem infeasible or failed).
    ///
    /// # Errors
    /// [`PtrError::NotRunning`] before [`start`](Self::start) or after a final iteration; a
    /// dynamics evaluation error.
    pub fn step(&mut self) -> Result<Iteration, PtrError> {
        let mut st = self.state.take().ok_or(PtrError::NotRunning)?;
        let out =
            if st.status.is_some() { Err(PtrError::NotRunning) } else { self.step_in(&mut st) };
        self.state = Some(st);
        out
    }

    /// Drops the cost of the running solve: from the next [`step`](Self::step) on, its
    /// subproblems have no objective but the prices of the virtual controls and buffers and
    /// the trust region, so the solve only restores feasibility near the current reference
    /// and stops by the usual test (short step, defects and violations within tolerance).
    /// For a caller that judges the iterates by its own measure — e.g. the final time of
    /// their path retimed, which the solve's own timing no longer improves — and has what it
    /// needs once the trajectory is feasible. The iterations after it are marked
    /// ([`Iteration::feasibility`]); [`start`](Self::start) restores the cost.
    ///
    /// # Errors
    /// [`PtrError::NotRunning`] before [`start`](Self::start) or after a final iteration.
    pub fn restore_feasibility_only(&mut self) -> Result<(), PtrError> {
        let mut st = self.state.take().ok_or(PtrError::NotRunning)?;
        if st.status.is_some() {
            self.state = Some(st);
            return Err(PtrError::NotRunning);
        }
        self.cost_on = false;
        // The reference's merit without the cost, for the next step's ratio.
        let prices = (&st.lam_vc[..], &st.lam_vb[..]);
        let (xb, ub, sb) = (&st.xb, &st.ub, &st.sb);
        (st.jbar, _, _, _) =
            self.merit(xb, ub, sb, &st.dbar, &mut st.ev, prices, GridAt::Reference);
        self.state = Some(st);
        Ok(())
    }

    /// Drops the cost of the running solve as [`restore_feasibility_only`](
    /// Self::restore_feasibility_only) does, and moves its reference back to `(x, u, s)` (an
    /// earlier iterate of the same solve, as a monitor keeps it): the solve then restores
    /// feasibility near that trajectory instead of the current one. The weights, the trust
    /// region, the multipliers and the history carry on.
    ///
    /// # Errors
    /// [`PtrError::NotRunning`] before [`start`](Self::start) or after a final iteration;
    /// [`PtrError::GuessSize`] / [`PtrError::GuessNotFinite`] for a trajectory that does not fit;
    /// a dynamics evaluation error.
    pub fn restore_feasibility_from(
        &mut self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
    ) -> Result<(), PtrError> {
        self.check_trajectory(x, u, s)?;
        let mut st = self.state.take().ok_or(PtrError::NotRunning)?;
        let out = if st.status.is_some() {
            Err(PtrError::NotRunning)
        } else {
            self.set_reference(&mut st, x, u, s)
        };
        if out.is_ok() {
            if let Some(native) = st.native.as_mut() {
                native.restart();
            }
            // The kept trajectory's final time (its merit follows, without the cost, below).
            st.tf = self.final_time(s);
        }
        self.state = Some(st);
        out?;
        self.restore_feasibility_only()
    }

    /// Sets the reference to `(x, u, s)` (checked) and discretizes it; the linearization and
    /// the curvature are then stale. The discretization's time is added to the timings.
    fn set_reference(
        &mut self,
        st: &mut Iterate,
        x: &[f64],
        u: &[f64],
        s: &[f64],
    ) -> Result<(), PtrError> {
        st.xb.copy_from_slice(x);
        st.ub.copy_from_slice(u);
        st.sb.copy_from_slice(s);
        let t0 = Instant::now();
        let disc = self.ocp.dynamics.discretize(
            x,
            u,
            s,
            &self.settings.discretization,
            &mut self.dws,
            &mut st.dbar,
        );
        st.timings.discretization_ms += t0.elapsed().as_secs_f64() * 1e3;
        st.hess_ready.fill(false);
        st.linearized = false;
        st.ev.fgrid_reference = false;
        disc.map_err(Into::into)
    }

    /// Checks a trajectory `(x, u, s)` for this problem: sizes (N×n, N×m, N), finite values.
    fn check_trajectory(&self, x: &[f64], u: &[f64], s: &[f64]) -> Result<(), PtrError> {
        let (n, m, nodes) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        for (what, v, len) in [("x", x, nodes * n), ("u", u, nodes * m), ("s", s, nodes)] {
            if v.len() != len {
                return Err(PtrError::GuessSize { what, expected: len, got: v.len() });
            }
            if let Some(index) = v.iter().position(|v| !v.is_finite()) {
                return Err(PtrError::GuessNotFinite { what, index });
            }
        }
        Ok(())
    }

    /// Whether the running solve still minimizes its cost (see
    /// [`restore_feasibility_only`](Self::restore_feasibility_only)).
    pub fn cost_on(&self) -> bool {
        self.cost_on
    }

    /// The current reference trajectory (the last accepted one), once started.
    pub fn trajectory(&self) -> Option<Trajectory<'_>> {
        self.state.as_ref().map(|st| Trajectory {
            nodes: self.ocp.nodes,
            x: &st.xb,
            u: &st.ub,
            s: &st.sb,
            final_time: st.tf,
        })
    }

    /// The result so far: the reference trajectory, its constraint violations, the history
    /// and the status (`MaxIterations` while still running).
    pub fn result(&mut self) -> Option<PtrResult> {
        let mut st = self.state.take()?;
        let violations = self.violations(&mut st);
        let max_violation = violations
            .iter()
            .filter(|v| v.value > 0.0)
            .max_by(|a, b| a.value.total_cmp(&b.value))
            .cloned();
        let r = PtrResult {
            status: st.status.unwrap_or(PtrStatus::MaxIterations),
            x: st.xb.clone(),
            u: st.ub.clone(),
            s: st.sb.clone(),
            final_time: st.tf,
            history: st.history.clone(),
            violations,
            max_violation,
            timings: st.timings,
            prices: self.prices_of(&st),
        };
        self.state = Some(st);
        Some(r)
    }

    /// An empty discretization for this problem (with the integration grid when it has
    /// interval bounds).
    pub(super) fn output(&self) -> Discretization {
        let nn = self.ocp.nodes;
        if self.peaks.is_empty() && !self.settings.exact_hessian {
            self.ocp.dynamics.output(nn)
        } else {
            self.ocp.dynamics.output_with_grid(nn, self.settings.discretization.substeps)
        }
    }
}
