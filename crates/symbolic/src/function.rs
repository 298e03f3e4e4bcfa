//! Compiled functions: values and sparse Jacobians of a set of outputs w.r.t. ordered
//! input groups.

use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

use crate::lower::{Builder, InputInfo, ParamInfo};
use crate::tape::{Arg, Tape, Workspace};
use crate::{Expr, HessianPattern, Shape, SparsityPattern, SymbolicError};

/// How a compiled function propagates derivatives. Both give the same values, the same
/// sparse Jacobian pattern and the same nonzeros (up to round-off); they differ in speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DerivativeMode {
    /// Dense rows for functions with at most [`DENSE_MAX_INPUTS`] inputs and no `vmap`,
    /// sparse otherwise.
    #[default]
    Auto,
    /// Each scalar carries only the input columns it depends on (scales with sparsity).
    Sparse,
    /// Each scalar carries a full gradient row (branch-free; best for few inputs). Up to
    /// [`DENSE_MAX_INPUTS`] inputs; sparse beyond.
    Dense,
}

/// Input count up to which [`DerivativeMode::Auto`] chooses dense rows.
pub const DENSE_MAX_INPUTS: usize = 16;

/// One named variable of an input group and where its entries sit in the input vector.
#[derive(Debug, Clone, PartialEq)]
pub struct InputSlot {
    /// The variable's name.
    pub name: String,
    /// Its shape.
    pub shape: Shape,
    /// Offset of its first entry in the concatenated input vector.
    pub offset: usize,
}

/// A compiled set of outputs: a flat scalar tape with a Jacobian sparsity pattern fixed at
/// compile time.
///
/// The input vector is the concatenation of the input groups (e.g. `[x; u]`), each group the
/// concatenation of its variables' entries (row-major). The output vector is the
/// concatenation of the outputs' entries. [`eval`](Self::eval) writes values and the
/// Jacobian's nonzeros (in [`jacobian_pattern`](Self::jacobian_pattern) order) into
/// caller-provided buffers and allocates nothing.
///
/// # Example
/// ```
/// use armature_symbolic::{Expr, Function};
///
/// let angle = Expr::variable("angle", 2);
/// let velocity = Expr::variable("velocity", 2);
/// let torque = Expr::variable("torque", 2);
/// let inertia_inv = Expr::constant_vector(&[1.0 / 0.08, 1.0 / 0.06]);
/// let f = Function::compile(
///     &[velocity.clone(), &inertia_inv * &torque],
///     &[&[angle, velocity], &[torque]],
/// )
/// .unwrap();
/// // d(angle')/d(velocity) and d(velocity')/d(torque) are diagonal: 4 nonzeros, not 24.
/// assert_eq!(f.jacobian_pattern().nnz(), 4);
/// let mut ws = f.workspace();
/// let (mut out, mut jac) = (vec![0.0; 4], vec![0.0; 4]);
/// f.eval(&[0.0, 0.0, 1.0, 2.0, 0.8, 0.6], &mut ws, &mut out, Some(&mut jac)).unwrap();
/// assert_eq!(out, vec![1.0, 2.0, 10.0, 10.0]);
/// assert_eq!(jac, vec![1.0, 1.0, 12.5, 1.0 / 0.06]);
/// ```
#[derive(Debug, Clone)]
pub struct Function {
    pub(crate) tape: Tape,
    pub(crate) outputs: Vec<Arg>,
    output_shapes: Vec<Shape>,
    groups: Vec<Vec<InputSlot>>,
    group_offsets: Vec<usize>,
    pub(crate) n_inputs: usize,
    params: Vec<ParamInfo>,
    pub(crate) param_values: Vec<f64>,
    pattern: SparsityPattern,
    /// For output entry k with slot s, the nonzero position of each of its dependency
    /// columns: `jac_pos[jac_start[k]..jac_start[k+1]]`.
    jac_start: Vec<u32>,
    jac_pos: Vec<u32>,
    pub(crate) dense: bool,
    /// The weighted Hessian's structure, computed on first use.
    pub(crate) hessian: OnceLock<HessianPattern>,
}

impl Function {
    /// Compiles `outputs` against ordered input groups of variables.
    ///
    /// # Errors
    /// The first error of any output expression; [`SymbolicError::NotAVariable`] for a group
    /// entry that is not a variable leaf; [`SymbolicError::DuplicateName`] for a variable
    /// listed twice or used with another shape; [`SymbolicError::UnknownVariable`] for a
    /// variable in an output that is in no group.
    pub fn compile(outputs: &[Expr], groups: &[&[Expr]]) -> Result<Function, SymbolicError> {
        Self::compile_with(outputs, groups, DerivativeMode::Auto)
    }

    /// [`compile`](Self::compile) with an explicit [`DerivativeMode`]. `Dense` falls back to
    /// sparse for functions that contain a `vmap` or have more than [`DENSE_MAX_INPUTS`]
    /// inputs.
    ///
    /// # Errors
    /// As [`compile`](Self::compile).
    pub fn compile_with(
        outputs: &[Expr],
        groups: &[&[Expr]],
        mode: DerivativeMode,
    ) -> Result<Function, SymbolicError> {
        let mut inputs: HashMap<Arc<str>, InputInfo> = HashMap::new();
        let mut slots = Vec::new();
        let mut group_offsets = vec![0];
        let mut offset = 0;
        for (g, group) in groups.iter().enumerate() {
            let mut gs = Vec::new();
            for (i, v) in group.iter().enumerate() {
                v.check()?;
                let name: Arc<str> = match &v.0.op {
                    crate::expr::Op::Variable(n) => n.clone(),
                    _ => return Err(SymbolicError::NotAVariable { group: g, index: i }),
                };
                let shape = v.0.shape;
                if inputs.insert(name.clone(), InputInfo { offset, shape }).is_some() {
                    return Err(SymbolicError::DuplicateName {
                        name: name.to_string(),
                        detail: "the variable is listed twice in the input groups".into(),
                    });
                }
                gs.push(InputSlot { name: name.to_string(), shape, offset });
                offset += shape.numel();
            }
            slots.push(gs);
            group_offsets.push(offset);
        }
        for o in outputs {
            o.check()?;
        }
        let mut b = Builder::new(&inputs, offset);
        let mut out_args = Vec::new();
        let mut output_shapes = Vec::new();
        for o in outputs {
            out_args.extend(b.lower(o, None)?);
            output_shapes.push(o.0.shape);
        }
        let mut entries = Vec::new();
        for (k, a) in out_args.iter().enumerate() {
            if let Arg::Slot(s) = a {
                entries.extend(b.slot_deps(*s).iter().map(|&c| (k, c as usize)));
            }
        }
        let (tape, params, param_values) = b.finish();
        let pattern = SparsityPattern::from_entries(out_args.len(), offset, &entries);
        let mut jac_start = vec![0u32];
        let mut jac_pos = Vec::new();
        for (k, a) in out_args.iter().enumerate() {
            if let Arg::Slot(s) = a {
                for &c in tape.deps(*s) {
                    jac_pos
                        .push(pattern.position(k, c as usize).expect("entry is in the pattern")
                            as u32);
                }
            }
            jac_start.push(jac_pos.len() as u32);
        }
        let dense = tape.vmaps.is_empty()
            && match mode {
                DerivativeMode::Auto => offset <= DENSE_MAX_INPUTS,
                DerivativeMode::Sparse => false,
                DerivativeMode::Dense => offset <= DENSE_MAX_INPUTS,
            };
        Ok(Function {
            dense,
            tape,
            outputs: out_args,
            output_shapes,
            groups: slots,
            group_offsets,
            n_inputs: offset,
            params,
            param_values,
            pattern,
            jac_start,
            jac_pos,
            hessian: OnceLock::new(),
        })
    }

    /// Length of the input vector.
    pub fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    /// Length of the output vector.
    pub fn n_outputs(&self) -> usize {
        self.outputs.len()
    }

    /// Shapes of the outputs, in order.
    pub fn output_shapes(&self) -> &[Shape] {
        &self.output_shapes
    }

    /// The variables of input group `g` with their offsets.
    pub fn group(&self, g: usize) -> &[InputSlot] {
        &self.groups[g]
    }

    /// The input-vector range (= Jacobian column range) of group `g`.
    pub fn group_range(&self, g: usize) -> core::ops::Range<usize> {
        self.group_offsets[g]..self.group_offsets[g + 1]
    }

    /// The Jacobian's sparsity pattern (outputs × inputs), fixed at compile time and
    /// structurally complete: every entry that can be nonzero for some input is in it.
    pub fn jacobian_pattern(&self) -> &SparsityPattern {
        &self.pattern
    }

    /// Number of scalar instructions of the tape (a measure of evaluation cost, and of how
    /// much constant folding and CSE removed).
    pub fn instruction_count(&self) -> usize {
        self.tape.instrs.len()
    }

    /// Names of the parameters this function reads.
    pub fn parameter_names(&self) -> impl Iterator<Item = &str> {
        self.params.iter().map(|p| &*p.name)
    }

    /// Current value of a parameter.
    pub fn parameter(&self, name: &str) -> Option<&[f64]> {
        self.params
            .iter()
            .find(|p| &*p.name == name)
            .map(|p| &self.param_values[p.offset..p.offset + p.shape.numel()])
    }

    /// Sets a parameter's value (row-major); the next evaluation uses it, nothing recompiles.
    ///
    /// # Errors
    /// [`SymbolicError::UnknownParameter`], [`SymbolicError::BufferLength`], or
    /// [`SymbolicError::BadData`] for a non-finite value.
    pub fn set_parameter(&mut self, name: &str, value: &[f64]) -> Result<(), SymbolicError> {
        let p = self
            .params
            .iter()
            .find(|p| &*p.name == name)
            .ok_or_else(|| SymbolicError::UnknownParameter { name: name.to_string() })?;
        let n = p.shape.numel();
        if value.len() != n {
            return Err(SymbolicError::BufferLength {
                what: "parameter value",
                expected: n,
                got: value.len(),
            });
        }
        if let Some(i) = value.iter().position(|x| !x.is_finite()) {
            return Err(SymbolicError::BadData {
                what: "parameter",
                name: name.to_string(),
                reason: format!("entry {i} is {}", value[i]),
            });
        }
        self.param_values[p.offset..p.offset + n].copy_from_slice(value);
        Ok(())
    }

    /// A workspace for [`eval`](Self::eval) (allocates; create once, reuse).
    pub fn workspace(&self) -> Workspace {
        if self.dense { self.tape.workspace_dense() } else { self.tape.workspace() }
    }

    /// Whether derivatives propagate as dense rows (see [`DerivativeMode`]).
    pub fn is_dense(&self) -> bool {
        self.dense
    }

    /// Evaluates the outputs into `values` and, if given, the Jacobian's nonzeros into
    /// `jacobian` (in [`jacobian_pattern`](Self::jacobian_pattern) order). Allocation-free.
    ///
    /// # Errors
    /// [`SymbolicError::BufferLength`] if a buffer has the wrong length.
    pub fn eval(
        &self,
        input: &[f64],
        ws: &mut Workspace,
        values: &mut [f64],
        jacobian: Option<&mut [f64]>,
    ) -> Result<(), SymbolicError> {
        self.check(input, ws, values, jacobian.as_deref().map(<[f64]>::len))?;
        if self.dense {
            self.tape.run_dense(input, &self.param_values, ws, jacobian.is_some());
        } else {
            self.tape.run(input, &self.param_values, ws, jacobian.is_some());
        }
        self.read_values(ws, values);
        if let Some(jac) = jacobian {
            self.read_jacobian(ws, jac, None);
        }
        Ok(())
    }

    /// Like [`eval`](Self::eval) with the Jacobian, for outputs that often have exactly
    /// zero derivatives: the value of every output, and the Jacobian rows of the outputs
    /// marked in `needed` (all if `None`); the other rows' entries are set to zero.
    ///
    /// Derivatives are propagated only along paths that reach a needed output through
    /// nonzero local partials. An inactive ReLU (`pos`, `squared_pos` at x ≤ 0), the
    /// operand `max` / `min` did not select, and a factor multiplied by an exact zero cut
    /// the paths through them, so a penalty `Σ pos(g_i)` whose constraints all hold costs
    /// little more than its value. The result equals [`eval`](Self::eval)'s on the needed
    /// rows. For a function with few inputs (dense derivative rows, see
    /// [`is_dense`](Self::is_dense)) nothing is pruned: the rows are computed by `eval`.
    ///
    /// Cost: one value pass, one backward marking pass, then the derivative work of the
    /// instructions on needed paths (their local partials recomputed). On the seed arm's
    /// dynamics (350 instructions; forward kinematics shared by four CTCS penalties), one
    /// evaluation takes 1.6 µs instead of [`eval`](Self::eval)'s 2.2 µs where the penalties
    /// are inactive and 2.7 µs where they are active; a whole discretization of the seed
    /// trajectory, 8 % less time.
    ///
    /// # Errors
    /// [`SymbolicError::BufferLength`] if a buffer (or `needed`) has the wrong length.
    ///
    /// # Example
    /// ```
    /// use armature_symbolic::{Expr, Function};
    /// let x = Expr::variable("x", 2);
    /// // One output that is a penalty of x₀ − 1 and one that is x₁²: at x₀ = 0.5 the penalty
    /// // is inactive, and its row of the Jacobian is zero without being propagated.
    /// let f = Function::compile(&[(x.at(0) - 1.0).pos(), x.at(1) * x.at(1)], &[&[x]]).unwrap();
    /// let mut ws = f.workspace();
    /// let (mut v, mut j) = ([0.0; 2], vec![0.0; f.jacobian_pattern().nnz()]);
    /// f.eval_pruned(&[0.5, 3.0], &mut ws, &mut v, &mut j, None).unwrap();
    /// assert_eq!(v, [0.0, 9.0]);
    /// assert_eq!(j, [0.0, 6.0]);
    /// // Only the second row: the first row's entries are zero whatever its value.
    /// f.eval_pruned(&[2.0, 3.0], &mut ws, &mut v, &mut j, Some(&[false, true])).unwrap();
    /// assert_eq!((v, j.as_slice()), ([1.0, 9.0], [0.0, 6.0].as_slice()));
    /// ```
    pub fn eval_pruned(
        &self,
        input: &[f64],
        ws: &mut Workspace,
        values: &mut [f64],
        jacobian: &mut [f64],
        needed: Option<&[bool]>,
    ) -> Result<(), SymbolicError> {
        self.check(input, ws, values, Some(jacobian.len()))?;
        if let Some(m) = needed
            && m.len() != self.outputs.len()
        {
            return Err(SymbolicError::BufferLength {
                what: "needed",
                expected: self.outputs.len(),
                got: m.len(),
            });
        }
        let is_needed = |k: usize| needed.is_none_or(|m| m[k]);
        if self.dense {
            self.tape.run_dense(input, &self.param_values, ws, true);
        } else {
            ws.active.fill(false);
            for (k, a) in self.outputs.iter().enumerate() {
                if let (Arg::Slot(s), true) = (*a, is_needed(k)) {
                    ws.active[s as usize] = true;
                }
            }
            self.tape.run_pruned(input, &self.param_values, ws);
        }
        self.read_values(ws, values);
        self.read_jacobian(ws, jacobian, needed);
        Ok(())
    }

    /// Buffer lengths and the workspace's tape.
    pub(crate) fn check(
        &self,
        input: &[f64],
        ws: &Workspace,
        values: &[f64],
        jacobian: Option<usize>,
    ) -> Result<(), SymbolicError> {
        let check = |what, expected: usize, got: usize| {
            if expected == got {
                Ok(())
            } else {
                Err(SymbolicError::BufferLength { what, expected, got })
            }
        };
        check("input", self.n_inputs, input.len())?;
        check("values", self.outputs.len(), values.len())?;
        if let Some(j) = jacobian {
            check("jacobian", self.pattern.nnz(), j)?;
        }
        if ws.tape_id != self.tape.id {
            return Err(SymbolicError::ForeignWorkspace);
        }
        Ok(())
    }

    /// The output values after a run.
    pub(crate) fn read_values(&self, ws: &Workspace, values: &mut [f64]) {
        for (v, a) in values.iter_mut().zip(&self.outputs) {
            *v = match *a {
                Arg::Const(c) => c,
                Arg::Slot(s) => ws.val[s as usize],
            };
        }
    }

    /// The Jacobian's nonzeros after a run with derivatives; the rows not `needed` are zero.
    pub(crate) fn read_jacobian(&self, ws: &Workspace, jac: &mut [f64], needed: Option<&[bool]>) {
        for (k, a) in self.outputs.iter().enumerate() {
            let pos = &self.jac_pos[self.jac_start[k] as usize..self.jac_start[k + 1] as usize];
            let slot = match *a {
                Arg::Slot(s) if needed.is_none_or(|m| m[k]) => s,
                _ => {
                    for &p in pos {
                        jac[p as usize] = 0.0;
                    }
                    continue;
                }
            };
            if self.dense {
                let row = &ws.dval[slot as usize * self.tape.dense_stride()..];
                for (&c, &p) in self.tape.deps(slot).iter().zip(pos) {
                    jac[p as usize] = row[c as usize];
                }
            } else {
                let base = self.tape.dep_off[slot as usize] as usize;
                for (j, &p) in pos.iter().enumerate() {
                    jac[p as usize] = ws.dval[base + j];
                }
            }
        }
    }
}
