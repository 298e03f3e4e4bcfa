//! [`Problem::compile`] as passes: sort the constraints by timing (CTCS groups, nodal,
//! continuous), augment the dynamics with the CTCS integrals, compile the nodal, ball and
//! between-nodes constraints, the dense checks and the outputs, then assemble the [`Ocp`],
//! the guess and the names the reports use.

use super::*;

/// CTCS groups by (interval, options), in order of first appearance.
type Groups = Vec<(CtcsGroup, CtcsOptions)>;

/// A problem's constraints sorted by timing.
struct Timed<'a> {
    groups: Groups,
    /// What each group integrates, for violation reports.
    group_names: Vec<Vec<String>>,
    /// Nodal constraints with their resolved nodes.
    nodal_specs: Vec<(&'a Constraint, Vec<usize>)>,
    /// Continuous constraints for the dense checks: (name, g, first node, last node).
    continuous: Vec<(String, Expr, usize, usize)>,
}

/// The dynamics with one CTCS integral per group appended, gated to its interval.
struct Augmented {
    dynamics: Dynamics,
    state_exprs: Vec<Expr>,
    control_exprs: Vec<Expr>,
    /// Components of the named states (the integrals follow).
    n_named: usize,
}

impl Problem {
    /// Checks the problem and compiles it: dynamics, CTCS groups, nodal constraints and
    /// outputs become compiled functions, the subproblem pattern is built once, and the
    /// guess is prepared.
    ///
    /// # Errors
    /// [`ProblemError`] saying what is wrong and where: sizes that do not match, bounds
    /// that cross, NaN, a fixed value outside its bounds, a node out of range, a constraint
    /// or expression that does not compile, unusable settings.
    pub fn compile(&self, settings: PtrSettings) -> Result<CompiledProblem, ProblemError> {
        settings.validate().map_err(PtrError::from)?;
        let nn = self.nodes;
        if !(2..=MAX_NODES).contains(&nn) {
            return Err(bad("nodes", format!("need 2 to {MAX_NODES}, got {nn}")));
        }
        if (nn - 1).saturating_mul(settings.discretization.substeps) > crate::MAX_GRID_STEPS {
            return Err(bad(
                "discretization.substeps",
                format!(
                    "{} per segment over {} segments: at most {} steps in all",
                    settings.discretization.substeps,
                    nn - 1,
                    crate::MAX_GRID_STEPS
                ),
            ));
        }
        self.check_variables()?;
        let longest = match self.time {
            Time::Fixed(t) => t,
            Time::Free { max, .. } => max,
        };
        // Before the time's own checks: a maximum too long to sample is the clearer error.
        if longest / settings.dense_dt > MAX_DENSE_SAMPLES as f64 {
            return Err(bad(
                "time",
                format!(
                    "a final time of up to {longest:.4e} s at dense_dt {:.4e} s would take \
                     {:.4e} samples of the dense trajectory; at most {MAX_DENSE_SAMPLES} (lower \
                     the time's maximum or raise dense_dt)",
                    settings.dense_dt,
                    longest / settings.dense_dt
                ),
            ));
        }
        let dilation = self.check_time()?;
        let Timed { groups, group_names, nodal_specs, continuous } = self.sort_constraints()?;
        let Augmented { dynamics, state_exprs, control_exprs, n_named } =
            self.augmented_dynamics(&groups)?;
        let n = n_named + groups.len();
        let args = [state_exprs.as_slice(), control_exprs.as_slice()];
        let nodal = self.nodal_constraints(nodal_specs, &args)?;
        let interval_constraints = self.interval_constraints(&args, n)?;
        let dense_checks = self.dense_checks(continuous, &interval_constraints, &args)?;
        let (outputs, output_fn) = self.outputs(&args)?;
        let parts = (dynamics, nodal, interval_constraints);
        let ocp = self.ocp(parts, &groups, n_named, dilation);
        refuse_time_scaled_reads(&ocp)?;
        let guess = self.guess(&ocp, n, &settings)?;
        let blocks = |names: Vec<(String, usize)>| {
            let mut off = 0;
            names
                .into_iter()
                .map(|(name, size)| {
                    let b = Block { name, offset: off, size };
                    off += size;
                    b
                })
                .collect::<Vec<_>>()
        };
        let ctcs_names = group_names
            .iter()
            .enumerate()
            .map(|(i, names)| {
                let (g, o) = &groups[i];
                (
                    format!("_ctcs_{i}"),
                    format!(
                        "continuous-time {} (nodes {}..={}, ε = {:e})",
                        names.join(", "),
                        g.first,
                        g.last,
                        o.eps
                    ),
                )
            })
            .collect();
        Ok(CompiledProblem {
            ctcs_names,
            ctcs_row0: n_named,
            dense_checks,
            layout: SolutionLayout {
                states: blocks(self.states.iter().map(|s| (s.name.clone(), s.size())).collect()),
                controls: blocks(
                    self.controls.iter().map(|c| (c.name.clone(), c.size())).collect(),
                ),
                outputs,
                output_fn,
                n,
                m: self.controls.iter().map(Control::size).sum(),
                holds: ocp.dynamics.holds(),
            },
            ptr: Ptr::new(ocp, settings.clone())?,
            monitor: None,
            settings,
            guess,
        })
    }

    /// Pass 1: CTCS groups (with the state bounds' when held between nodes), nodal
    /// constraints with their nodes, and the continuous ones for the dense checks.
    fn sort_constraints(&self) -> Result<Timed<'_>, ProblemError> {
        let nn = self.nodes;
        // CTCS groups by (interval, penalty, ε), in order of first appearance.
        let mut groups: Vec<(CtcsGroup, CtcsOptions)> = Vec::new();
        // What each group integrates, for violation reports.
        let mut group_names: Vec<Vec<String>> = Vec::new();
        let mut add = |g: Expr, first: usize, last: usize, o: CtcsOptions, name: &str| {
            let i = match groups
                .iter()
                .position(|(c, go)| (c.first, c.last) == (first, last) && *go == o)
            {
                Some(i) => i,
                None => {
                    groups.push((
                        CtcsGroup { constraints: Vec::new(), first, last, penalty: o.penalty },
                        o,
                    ));
                    group_names.push(Vec::new());
                    groups.len() - 1
                }
            };
            groups[i].0.constraints.push(g);
            if !group_names[i].iter().any(|n| n == name) {
                group_names[i].push(name.to_string());
            }
        };
        if let Some(o) = self.state_bounds_ctcs {
            // Bounds held at every grid point (with the cubic margin) need no integral: its
            // kink where the motion rides the bound only slows the solve (BENCHMARKS.md).
            let gridded = |st: &&State| {
                st.interval_bounds && self.interval_bounds_sampling == crate::Sampling::GridPoints
            };
            for st in self.states.iter().filter(|st| !gridded(st)) {
                let e = st.expr();
                // Whole vectors where every component is bounded, else per component.
                if st.max.iter().all(|v| v.is_finite()) {
                    add(&e - Expr::constant_vector(&st.max), 0, nn - 1, o, "state bounds");
                } else {
                    for i in (0..st.size()).filter(|&i| st.max[i].is_finite()) {
                        add(e.at(i) - st.max[i], 0, nn - 1, o, "state bounds");
                    }
                }
                if st.min.iter().all(|v| v.is_finite()) {
                    add(Expr::constant_vector(&st.min) - &e, 0, nn - 1, o, "state bounds");
                } else {
                    for i in (0..st.size()).filter(|&i| st.min[i].is_finite()) {
                        add(Expr::scalar(st.min[i]) - e.at(i), 0, nn - 1, o, "state bounds");
                    }
                }
            }
        }
        let mut nodal_specs = Vec::new();
        let mut continuous = Vec::new();
        for pc in &self.constraints {
            let c = &pc.constraint;
            c.validate(nn).map_err(sym(format!("constraint \"{}\"", c.name())))?;
            if !(pc.ctcs.eps.is_finite() && pc.ctcs.eps > 0.0) {
                return Err(bad(format!("constraint \"{}\"", c.name()), "CTCS ε must be > 0"));
            }
            match c.timing() {
                Timing::Continuous(range) => {
                    let (a, b) = range.unwrap_or((0, nn - 1));
                    add(c.function().clone(), a, b, pc.ctcs, c.name());
                    let g = c.function().clone();
                    let g = if c.is_equality() { Expr::concat(&[g.clone(), -g]) } else { g };
                    continuous.push((c.name().to_string(), g, a, b));
                }
                Timing::Nodal(nodes) => nodal_specs.push((c, nodes.resolve(nn))),
            }
        }
        Ok(Timed { groups, group_names, nodal_specs, continuous })
    }

    /// Pass 2: the named states, then one integral per CTCS group, gated to its interval.
    fn augmented_dynamics(&self, groups: &Groups) -> Result<Augmented, ProblemError> {
        // States: the named ones, then one integral per CTCS group.
        let mut state_exprs: Vec<Expr> = self.states.iter().map(State::expr).collect();
        let mut rhs = self.dynamics.clone();
        let ctcs_groups: Vec<CtcsGroup> = groups.iter().map(|(g, _)| g.clone()).collect();
        for (y, f) in ctcs_states(&ctcs_groups) {
            state_exprs.push(y);
            rhs.push(f);
        }
        let control_exprs: Vec<Expr> = self.controls.iter().map(Control::expr).collect();
        let foh: Vec<bool> =
            self.controls.iter().flat_map(|c| std::iter::repeat_n(c.foh, c.size())).collect();
        let n_named: usize = self.states.iter().map(State::size).sum();
        let mut dynamics =
            Dynamics::new(&state_exprs, &control_exprs, &rhs, &foh).map_err(|e| match e {
                DiscretizationError::Symbolic(source) => {
                    ProblemError::Symbolic { what: "dynamics".into(), source }
                }
                DiscretizationError::Size(reason) => bad("dynamics", reason),
            })?;
        let scaled: Vec<bool> = self
            .controls
            .iter()
            .flat_map(|c| std::iter::repeat_n(c.time_scaled, c.size()))
            .collect();
        dynamics = dynamics.time_scaled(&scaled).map_err(|e| bad("controls", e.to_string()))?;
        for (i, (g, _)) in groups.iter().enumerate() {
            dynamics = dynamics
                .gate(n_named + i, g.first, g.last)
                .map_err(|e| bad("CTCS interval", e.to_string()))?;
        }
        Ok(Augmented { dynamics, state_exprs, control_exprs, n_named })
    }

    /// Pass 3: the nodal constraints (equalities as two inequalities) and the balls.
    fn nodal_constraints(
        &self,
        nodal_specs: Vec<(&Constraint, Vec<usize>)>,
        args: &[&[Expr]],
    ) -> Result<Vec<NodalConstraint>, ProblemError> {
        let nn = self.nodes;
        // Nodal constraints and balls.
        let mut nodal = Vec::new();
        for (c, nodes) in nodal_specs {
            let what = format!("constraint \"{}\"", c.name());
            let g = c.function();
            let f = Function::compile(&[g.clone()], args).map_err(sym(what.clone()))?;
            super::checks::never_holds(&f, &what, c.is_equality())?;
            nodal.push(NodalConstraint {
                name: c.name().to_string(),
                function: f,
                nodes: nodes.clone(),
                kind: NodalKind::Inequality,
                output_names: Vec::new(),
            });
            if c.is_equality() {
                let f = Function::compile(&[-g], args).map_err(sym(what))?;
                nodal.push(NodalConstraint {
                    name: format!("{} (reverse)", c.name()),
                    function: f,
                    nodes,
                    kind: NodalKind::Inequality,
                    output_names: Vec::new(),
                });
            }
        }
        for b in &self.balls {
            let what = format!("ball \"{}\"", b.name);
            if !(b.radius.is_finite() && b.radius > 0.0) {
                return Err(bad(what, format!("radius {} must be a positive number", b.radius)));
            }
            if b.nodes.is_empty() {
                return Err(bad(what, "no nodes"));
            }
            if let Some(k) = b.nodes.iter().find(|&&k| k >= nn) {
                return Err(bad(what, format!("node {k} is beyond the last node {}", nn - 1)));
            }
            nodal.push(NodalConstraint {
                name: b.name.clone(),
                function: Function::compile(&[b.g.clone()], args).map_err(sym(what))?,
                nodes: b.nodes.clone(),
                kind: NodalKind::Ball { radius: b.radius },
                output_names: Vec::new(),
            });
        }
        Ok(nodal)
    }

    /// Pass 4: the between-nodes constraints (`n` states, the integrals included).
    fn interval_constraints(
        &self,
        args: &[&[Expr]],
        n: usize,
    ) -> Result<Vec<IntervalConstraint>, ProblemError> {
        let nn = self.nodes;
        let mut interval_constraints = Vec::new();
        for c in &self.between_nodes {
            let what = format!("between-nodes constraint \"{}\"", c.name);
            if !(c.first < c.last && c.last < nn) {
                return Err(bad(
                    what,
                    format!(
                        "segments {}..{} must satisfy first < last ≤ {} (the last node)",
                        c.first,
                        c.last,
                        nn - 1
                    ),
                ));
            }
            let function = Function::compile(&[c.g.clone()], args).map_err(sym(what.clone()))?;
            if c.activation.is_some_and(|a| a.is_nan() || a <= 0.0) {
                return Err(bad(what, "its activation distance must be positive (or none)"));
            }
            let ic = IntervalConstraint {
                name: c.name.clone(),
                function,
                first: c.first,
                last: c.last,
                activation: c.activation,
                sampling: c.sampling,
            };
            if ic.reads_controls(n) {
                return Err(bad(what, "it reads a control; it may read the states only"));
            }
            interval_constraints.push(ic);
        }
        Ok(interval_constraints)
    }

    /// Pass 5: the outputs' blocks and their compiled function.
    fn outputs(&self, args: &[&[Expr]]) -> Result<(Vec<Block>, Option<Function>), ProblemError> {
        // Outputs.
        let mut outputs = Vec::new();
        let mut off = 0;
        for (name, e) in &self.outputs {
            let what = format!("output \"{name}\"");
            if outputs.iter().any(|b: &Block| &b.name == name) || self.is_variable_name(name) {
                return Err(bad(what, "name already used"));
            }
            let size = e.shape().map_err(sym(what))?.numel();
            outputs.push(Block { name: name.clone(), offset: off, size });
            off += size;
        }
        let output_fn = if self.outputs.is_empty() {
            None
        } else {
            let exprs: Vec<Expr> = self.outputs.iter().map(|(_, e)| e.clone()).collect();
            Some(Function::compile(&exprs, args).map_err(sym("outputs"))?)
        };
        Ok((outputs, output_fn))
    }

    /// Pass 6: the solver-level problem — bounds, boundary conditions, final cost, time,
    /// CTCS increments, interval bounds.
    fn ocp(
        &self,
        (dynamics, nodal, interval_constraints): (
            Dynamics,
            Vec<NodalConstraint>,
            Vec<IntervalConstraint>,
        ),
        groups: &Groups,
        n_named: usize,
        (s_lo, s_hi, s_scale): (f64, f64, Option<f64>),
    ) -> Ocp {
        let nn = self.nodes;
        // Bounds and boundary conditions.
        let mut x_min: Vec<f64> = self.states.iter().flat_map(|s| s.min.clone()).collect();
        let mut x_max: Vec<f64> = self.states.iter().flat_map(|s| s.max.clone()).collect();
        x_min.extend(vec![0.0; groups.len()]);
        x_max.extend(vec![f64::INFINITY; groups.len()]);
        let fixed = |b: &Boundary| if let Boundary::Fixed(v) = b { Some(*v) } else { None };
        let mut x_initial: Vec<Option<f64>> =
            self.states.iter().flat_map(|s| s.initial.iter().map(fixed)).collect();
        x_initial.extend(vec![Some(0.0); groups.len()]);
        let mut x_final: Vec<Option<f64>> =
            self.states.iter().flat_map(|s| s.terminal.iter().map(fixed)).collect();
        x_final.extend(vec![None; groups.len()]);
        let final_cost: Vec<(usize, f64)> = self
            .states
            .iter()
            .flat_map(|s| s.terminal.iter())
            .enumerate()
            .filter_map(|(i, b)| match b {
                Boundary::Minimize => Some((i, 1.0)),
                Boundary::Maximize => Some((i, -1.0)),
                _ => None,
            })
            .collect();
        let (time_weight, final_time) = match self.time {
            Time::Fixed(t) => (0.0, (t, t)),
            Time::Free { min, max, minimize, .. } => (if minimize { 1.0 } else { 0.0 }, (min, max)),
        };
        Ocp {
            dynamics,
            nodes: nn,
            x_min,
            x_max,
            u_min: self.controls.iter().flat_map(|c| c.min.clone()).collect(),
            u_max: self.controls.iter().flat_map(|c| c.max.clone()).collect(),
            x_initial,
            x_final,
            s_min: s_lo,
            s_max: s_hi,
            s_scale,
            final_time,
            time_weight,
            final_cost,
            increments: groups
                .iter()
                .enumerate()
                .map(|(i, (g, o))| crate::Increment {
                    state: n_named + i,
                    eps: o.eps,
                    first: g.first,
                    last: g.last,
                })
                .collect(),
            nodal,
            interval_bounds: {
                let mut rows = Vec::new();
                let mut offset = 0;
                for st in &self.states {
                    if st.interval_bounds {
                        rows.extend(offset..offset + st.size());
                    }
                    offset += st.size();
                }
                rows
            },
            interval_bounds_sampling: self.interval_bounds_sampling,
            interval_constraints,
        }
    }
}

/// Refuses a nodal constraint that reads a time-scaled control: at the nodes the solver holds
/// `w = s·u`, and the constraint would see `w` where its author wrote `u`.
///
/// # Errors
/// [`ProblemError::Bad`] naming the constraint and the control entry.
fn refuse_time_scaled_reads(ocp: &Ocp) -> Result<(), ProblemError> {
    let (d, n) = (&ocp.dynamics, ocp.dynamics.n_x());
    for c in &ocp.nodal {
        let read = c.function.jacobian_pattern().entries().map(|(_, col)| col);
        if let Some(col) = read.filter(|&col| col >= n).find(|&col| d.is_time_scaled(col - n)) {
            return Err(bad(
                format!("constraint \"{}\"", c.name),
                format!(
                    "reads control entry {} at the nodes, which is time-scaled (the solver holds \
                     the control times its segment's dilation there); constrain it through its \
                     bounds, or do not time-scale it",
                    col - n
                ),
            ));
        }
    }
    Ok(())
}
