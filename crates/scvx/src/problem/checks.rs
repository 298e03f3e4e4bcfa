//! The checks a [`Problem`] passes before it compiles (variables, time), its initial guess,
//! and what the dense trajectory is checked against.

use super::*;

impl Problem {
    /// What the dense trajectory is checked against: the continuous constraints
    /// `(name, g, first node, last node)`, the between-nodes constraints, and the named
    /// states' bounds when they are held in continuous time.
    pub(super) fn dense_checks(
        &self,
        continuous: Vec<(String, Expr, usize, usize)>,
        interval_constraints: &[IntervalConstraint],
        args: &[&[Expr]],
    ) -> Result<DenseChecks, ProblemError> {
        let mut checks = DenseChecks::default();
        for (name, g, first, last) in continuous {
            let what = format!("constraint \"{name}\"");
            let function = Function::compile(&[g], args).map_err(sym(what.clone()))?;
            never_holds(&function, &what, false)?;
            checks.paths.push(PathCheck { name, function, first, last });
        }
        for c in interval_constraints {
            checks.paths.push(PathCheck {
                name: c.name.clone(),
                function: c.function.clone(),
                first: c.first,
                last: c.last,
            });
        }
        let mut row = 0;
        for st in &self.states {
            let held = self.state_bounds_ctcs.is_some() || st.interval_bounds;
            for i in 0..st.size() {
                let (min, max) = (st.min[i], st.max[i]);
                if held && (min.is_finite() || max.is_finite()) {
                    let name =
                        if st.size() == 1 { st.name.clone() } else { format!("{}[{i}]", st.name) };
                    checks.bounds.push(BoundCheck { name, row, min, max });
                }
                row += 1;
            }
        }
        Ok(checks)
    }

    pub(super) fn is_variable_name(&self, name: &str) -> bool {
        name == "time"
            || self.states.iter().any(|s| s.name == name)
            || self.controls.iter().any(|c| c.name == name)
    }

    /// Names, sizes, bounds, boundary conditions and guesses of states and controls.
    pub(super) fn check_variables(&self) -> Result<(), ProblemError> {
        let nn = self.nodes;
        if self.states.is_empty() {
            return Err(bad("states", "the problem has none"));
        }
        if self.dynamics.len() != self.states.len() {
            return Err(bad(
                "dynamics",
                format!(
                    "{} right-hand sides for {} states",
                    self.dynamics.len(),
                    self.states.len()
                ),
            ));
        }
        let mut names: Vec<&str> = vec!["time"];
        let entries =
            self.states.iter().map(|s| ("state", &s.name, &s.min, &s.max, &s.guess)).chain(
                self.controls.iter().map(|c| ("control", &c.name, &c.min, &c.max, &c.guess)),
            );
        for (kind, name, min, max, guess) in entries {
            let what = format!("{kind} \"{name}\"");
            if name.is_empty() || name.starts_with('_') {
                return Err(bad(what, "names must be non-empty and not start with '_'"));
            }
            if names.contains(&name.as_str()) {
                return Err(bad(what, "name already used"));
            }
            names.push(name);
            let size = min.len();
            if size == 0 || max.len() != size {
                return Err(bad(what, format!("{} lower and {} upper bounds", size, max.len())));
            }
            for i in 0..size {
                if min[i].is_nan() || max[i].is_nan() || min[i] > max[i] {
                    return Err(bad(
                        what,
                        format!("bounds [{}, {}] of component {i}", min[i], max[i]),
                    ));
                }
            }
            if let Some(g) = guess {
                if g.len() != nn * size {
                    return Err(bad(
                        what,
                        format!("guess has {} entries, expected {}", g.len(), nn * size),
                    ));
                }
                if let Some(i) = g.iter().position(|v| !v.is_finite()) {
                    return Err(bad(what, format!("guess entry {i} is not finite")));
                }
            }
        }
        for (st, f) in self.states.iter().zip(&self.dynamics) {
            let what = format!("state \"{}\"", st.name);
            for (which, conds) in [("initial", &st.initial), ("final", &st.terminal)] {
                if conds.len() != st.size() {
                    return Err(bad(
                        &what,
                        format!("{} {which} conditions for {} components", conds.len(), st.size()),
                    ));
                }
                for (i, c) in conds.iter().enumerate() {
                    match *c {
                        Boundary::Fixed(v)
                            if !(v.is_finite() && st.min[i] <= v && v <= st.max[i]) =>
                        {
                            return Err(bad(
                                &what,
                                format!(
                                    "{which} value {v} of component {i} is outside [{}, {}]",
                                    st.min[i], st.max[i]
                                ),
                            ));
                        }
                        Boundary::Minimize | Boundary::Maximize if which == "initial" => {
                            return Err(bad(
                                &what,
                                "only final conditions can be minimized or maximized",
                            ));
                        }
                        _ => {}
                    }
                }
            }
            let len = f.shape().map_err(sym(format!("dynamics of \"{}\"", st.name)))?.numel();
            if len != st.size() {
                return Err(bad(
                    format!("dynamics of \"{}\"", st.name),
                    format!("{len} entries for a state of {}", st.size()),
                ));
            }
        }
        Ok(())
    }

    /// The dilation bounds `(s_min, s_max)` and trust-region unit after checking the time
    /// settings.
    ///
    /// By default they are measured against a horizon `H`: the maximum time, or four times
    /// the guess when that is shorter, so that a generous maximum (`max = 100` s for a
    /// 1 s motion) neither floors every segment's duration at `H/40` nor lets the trust
    /// region swing the dilations across `5·max`: `s ∈ [H/40, 5·max]`, unit `(5H − H/40)/2`.
    pub(super) fn check_time(&self) -> Result<(f64, f64, Option<f64>), ProblemError> {
        let horizon = match self.time {
            Time::Free { max, guess, .. } if guess > 0.0 => max.min(4.0 * guess),
            Time::Free { max, .. } | Time::Fixed(max) => max,
        };
        let t_max = match self.time {
            Time::Fixed(t) => {
                if !(t.is_finite() && t > 0.0) {
                    return Err(bad("time", format!("fixed final time {t} must be positive")));
                }
                t
            }
            Time::Free { min, max, guess, .. } => {
                if !(min.is_finite() && max.is_finite() && 0.0 <= min && min < max) {
                    return Err(bad(
                        "time",
                        format!("bounds [{min}, {max}] must be finite with 0 ≤ min < max"),
                    ));
                }
                if !(min <= guess && guess <= max) {
                    return Err(bad("time", format!("guess {guess} outside [{min}, {max}]")));
                }
                max
            }
        };
        let (lo, hi, unit) = match self.dilation {
            Some((lo, hi)) => (lo, hi, None),
            None => (
                horizon / 40.0,
                5.0 * t_max,
                Some((0.5 * (5.0 * horizon - horizon / 40.0)).max(1.0)),
            ),
        };
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
            return Err(bad("dilation", format!("bounds [{lo}, {hi}] must satisfy 0 < min < max")));
        }
        Ok((lo, hi, unit))
    }

    /// The guess: states and controls by name, uniform dilations, CTCS integrals along it.
    /// The dynamics at every node of the guess are finite: a NaN or ∞ there (a division by
    /// zero, the root or logarithm of a negative) is named by its state row and node, before
    /// any iteration runs.
    fn check_dynamics_at(&self, ocp: &Ocp, (x, u): (&[f64], &[f64])) -> Result<(), ProblemError> {
        let (n, m) = (ocp.dynamics.n_x(), ocp.dynamics.n_u());
        let f = ocp.dynamics.function();
        let mut ws = f.workspace();
        let mut values = vec![0.0; f.n_outputs()];
        let mut input = vec![0.0; n + m];
        let named: usize = self.states.iter().map(State::size).sum();
        for k in 0..self.nodes {
            input[..n].copy_from_slice(&x[k * n..(k + 1) * n]);
            input[n..].copy_from_slice(&u[k * m..(k + 1) * m]);
            f.eval(&input, &mut ws, &mut values, None).map_err(sym("dynamics at the guess"))?;
            if let Some(r) = values.iter().position(|v| !v.is_finite()) {
                let what = if r < named {
                    format!("dynamics of {}", ocp.dynamics.state_name(r).unwrap_or("a state"))
                } else {
                    format!("continuous-time constraint group {}", r - named)
                };
                return Err(bad(
                    what,
                    format!(
                        "evaluates to {} at node {k} of the initial guess (a division by zero, \
                         or the root or logarithm of a negative number?)",
                        values[r]
                    ),
                ));
            }
        }
        Ok(())
    }

    pub(super) fn guess(
        &self,
        ocp: &Ocp,
        n: usize,
        settings: &PtrSettings,
    ) -> Result<Guess, ProblemError> {
        let nn = self.nodes;
        let m: usize = self.controls.iter().map(Control::size).sum();
        let mut x = vec![0.0; nn * n];
        let mut off = 0;
        for st in &self.states {
            for i in 0..st.size() {
                let start = match st.initial[i] {
                    Boundary::Fixed(v) => Some(v),
                    _ => None,
                };
                let end = match st.terminal[i] {
                    Boundary::Fixed(v) => Some(v),
                    _ => None,
                };
                let (a, b) = match (start, end) {
                    (Some(a), Some(b)) => (a, b),
                    (Some(a), None) => (a, a),
                    (None, Some(b)) => (b, b),
                    (None, None) => {
                        (0.0f64.clamp(st.min[i], st.max[i]), 0.0f64.clamp(st.min[i], st.max[i]))
                    }
                };
                for k in 0..nn {
                    x[k * n + off + i] = match &st.guess {
                        Some(g) => g[k * st.size() + i],
                        None => a + (b - a) * k as f64 / (nn - 1) as f64,
                    };
                }
            }
            off += st.size();
        }
        let mut u = vec![0.0; nn * m];
        let mut off = 0;
        for c in &self.controls {
            for k in 0..nn {
                for i in 0..c.size() {
                    u[k * m + off + i] = match &c.guess {
                        Some(g) => g[k * c.size() + i],
                        None => 0.0f64.clamp(c.min[i], c.max[i]),
                    };
                }
            }
            off += c.size();
        }
        let t = match self.time {
            Time::Fixed(t) => t,
            Time::Free { guess, .. } => guess,
        };
        let s = vec![t.clamp(ocp.s_min, ocp.s_max); nn];
        self.check_dynamics_at(ocp, (&x, &u))?;
        // The CTCS integrals along the guess (no defects in those rows from the start).
        let named: usize = self.states.iter().map(State::size).sum();
        if n > named {
            let d = &ocp.dynamics;
            let mut ws = d.workspace();
            let mut out = d.output(nn);
            let mut w = u.clone();
            d.holds().to_solver(&mut w, &s);
            d.discretize(&x, &w, &s, &settings.discretization, &mut ws, &mut out)
                .map_err(PtrError::from)?;
            for k in 0..nn - 1 {
                for r in named..n {
                    x[(k + 1) * n + r] = out.x_prop[k * n + r].max(0.0);
                }
            }
        }
        Ok((x, u, s))
    }
}

/// Refuses a constraint `g ≤ 0` (`g = 0` with `equality`) that reads no state or control and
/// does not hold: no trajectory can satisfy it, so no solve should start (`2 <= 1`).
///
/// # Errors
/// [`ProblemError::Bad`] naming the constraint and its value.
pub(super) fn never_holds(f: &Function, what: &str, equality: bool) -> Result<(), ProblemError> {
    if f.jacobian_pattern().nnz() > 0 {
        return Ok(());
    }
    let mut values = vec![0.0; f.n_outputs()];
    f.eval(&vec![0.0; f.n_inputs()], &mut f.workspace(), &mut values, None)
        .map_err(sym(what.to_string()))?;
    let broken = |v: &f64| !v.is_finite() || if equality { v.abs() > 1e-12 } else { *v > 0.0 };
    match values.iter().find(|v| broken(v)) {
        Some(v) => Err(bad(
            what,
            format!(
                "reads no state or control and never holds (its g is {v}, needs g {})",
                if equality { "= 0" } else { "≤ 0" }
            ),
        )),
        None => Ok(()),
    }
}
