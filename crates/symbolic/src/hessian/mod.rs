//! Exact sparse second derivatives: the weighted Hessian `H(x, w) = ∇²(wᵀf)(x)` of a
//! compiled [`Function`], its Hessian-vector products, and its structure.
//!
//! # Method
//! Forward gradients, then one second-order reverse sweep ([`sweep`]): the forward pass
//! the Jacobian already does leaves every slot's gradient; the backward pass carries
//! scalar adjoints and adds, at each curved instruction, its local second derivatives
//! contracted with its operands' gradients. This beats forward-over-forward (hyper-dual)
//! here because linear instructions — most of a product-of-exponentials chain — cost no
//! Hessian work at all, and instructions with a zero adjoint are skipped; it beats
//! forward-over-reverse (n reverse sweeps) because it needs one. With few inputs (dense
//! derivative rows) the terms go into an `N × N` square with fixed-width loops; otherwise
//! into the sparse lower triangle. A Hessian-vector product of a function with many inputs
//! runs the same sweep with the terms applied to `v` directly, so it needs neither the
//! pattern nor `n²` memory (with few inputs it multiplies the square).

mod accumulate;
mod coefficients;
mod jet;
mod lie;
mod pattern;
mod sweep;

pub use pattern::HessianPattern;

use crate::tape::{Arg, Workspace};
use crate::{Function, SymbolicError};

use accumulate::{DenseSquare, HessianVector, SparseLower};
use sweep::{SecondOrder, reverse};

/// Scratch memory for [`Function::eval_hessian`] and
/// [`Function::hessian_vector_product`]: create it once with
/// [`Function::hessian_workspace`] and reuse it; evaluations then allocate nothing.
#[derive(Debug, Clone)]
pub struct HessianWorkspace {
    fwd: Workspace,
    so: SecondOrder,
    /// The dense `N × N` square of functions with dense derivative rows (empty otherwise).
    square: Vec<f64>,
}

impl Function {
    /// The structure of the weighted Hessian (computed from the tape on first use, then
    /// kept).
    pub fn hessian_pattern(&self) -> &HessianPattern {
        self.hessian.get_or_init(|| HessianPattern::of(&self.tape))
    }

    /// A workspace for [`eval_hessian`](Self::eval_hessian) (allocates; create once).
    pub fn hessian_workspace(&self) -> HessianWorkspace {
        let _ = self.hessian_pattern();
        let stride = self.tape.dense_stride();
        HessianWorkspace {
            fwd: self.workspace(),
            so: SecondOrder::new(&self.tape),
            square: if self.dense { vec![0.0; stride * stride] } else { Vec::new() },
        }
    }

    /// Values, optionally the Jacobian, and the weighted Hessian `Σᵢ wᵢ ∇²fᵢ(x)` in one
    /// pass (the Hessian's lower-triangle nonzeros in [`hessian_pattern`] order).
    /// Allocation-free.
    ///
    /// Kinks take one-sided second derivatives matching the first derivatives: `abs`,
    /// `pos`, `max`, `min`, `‖·‖∞` and `‖·‖₁` have none; `squared_pos` has 2 for x > 0 and 0
    /// otherwise; `‖u‖₂` has `(I − ûûᵀ)/‖u‖` and 0 at the origin; `sqrt` has 0 at 0.
    ///
    /// [`hessian_pattern`]: Self::hessian_pattern
    ///
    /// # Errors
    /// [`SymbolicError::BufferLength`] for a buffer of the wrong length,
    /// [`SymbolicError::ForeignWorkspace`] for another function's workspace.
    ///
    /// # Example
    /// ```
    /// use armature_symbolic::{Expr, Function};
    /// let x = Expr::variable("x", 2);
    /// // f = (x₀²x₁, sin x₁); weights (2, 1): H = 2·[[2x₁, 2x₀], [2x₀, 0]] + [[0, 0], [0, −sin x₁]].
    /// let f = Function::compile(&[x.at(0).square() * x.at(1), x.at(1).sin()], &[&[x]]).unwrap();
    /// let mut hws = f.hessian_workspace();
    /// let mut v = [0.0; 2];
    /// let mut h = vec![0.0; f.hessian_pattern().nnz()];
    /// f.eval_hessian(&[3.0, 0.5], &[2.0, 1.0], &mut hws, &mut v, None, &mut h).unwrap();
    /// let dense = f.hessian_pattern().to_dense(&h);
    /// assert_eq!(dense[0], 2.0 * 2.0 * 0.5);
    /// assert_eq!(dense[1], 2.0 * 2.0 * 3.0);
    /// assert!((dense[3] + 0.5f64.sin()).abs() < 1e-15);
    /// ```
    pub fn eval_hessian(
        &self,
        input: &[f64],
        weights: &[f64],
        hws: &mut HessianWorkspace,
        values: &mut [f64],
        jacobian: Option<&mut [f64]>,
        hessian: &mut [f64],
    ) -> Result<(), SymbolicError> {
        let pattern = self.hessian_pattern();
        self.check_hessian(weights, hessian.len(), pattern.nnz())?;
        self.forward_and_seed(input, weights, hws, values, jacobian)?;
        let HessianWorkspace { fwd, so, square } = hws;
        if self.dense {
            square.fill(0.0);
            self.dense_sweep(fwd, so, square);
            let n = self.tape.dense_stride();
            for ((r, c), h) in pattern.lower().entries().zip(hessian.iter_mut()) {
                *h = square[r * n + c];
            }
        } else {
            hessian.fill(0.0);
            reverse(&self.tape, fwd, so, &mut SparseLower { pattern: pattern.lower(), h: hessian });
        }
        Ok(())
    }

    /// `H(x, w)·v` and the values. With sparse derivative rows H is not formed: the sweep
    /// of [`eval_hessian`](Self::eval_hessian) applies each term to `v` (no pattern, no `n²`
    /// memory); with dense rows (few inputs) the small square is formed and multiplied.
    /// Allocation-free.
    ///
    /// # Errors
    /// As [`eval_hessian`](Self::eval_hessian); `direction` and `out` have the input length.
    pub fn hessian_vector_product(
        &self,
        input: &[f64],
        weights: &[f64],
        direction: &[f64],
        hws: &mut HessianWorkspace,
        values: &mut [f64],
        out: &mut [f64],
    ) -> Result<(), SymbolicError> {
        let n = self.n_inputs;
        self.check_hessian(weights, n, n)?;
        for (what, got) in [("direction", direction.len()), ("output", out.len())] {
            if got != n {
                return Err(SymbolicError::BufferLength { what, expected: n, got });
            }
        }
        self.forward_and_seed(input, weights, hws, values, None)?;
        let HessianWorkspace { fwd, so, square } = hws;
        if self.dense {
            // Few inputs: the fixed-width square and one product are cheaper than applying
            // every term to v.
            square.fill(0.0);
            self.dense_sweep(fwd, so, square);
            let stride = self.tape.dense_stride();
            for (i, o) in out.iter_mut().enumerate() {
                *o = square[i * stride..i * stride + n]
                    .iter()
                    .zip(direction)
                    .map(|(h, v)| h * v)
                    .sum();
            }
        } else {
            out.fill(0.0);
            reverse(&self.tape, fwd, so, &mut HessianVector { v: direction, out });
        }
        Ok(())
    }

    fn check_hessian(
        &self,
        weights: &[f64],
        got: usize,
        expected: usize,
    ) -> Result<(), SymbolicError> {
        if weights.len() != self.outputs.len() {
            return Err(SymbolicError::BufferLength {
                what: "weights",
                expected: self.outputs.len(),
                got: weights.len(),
            });
        }
        if got != expected {
            return Err(SymbolicError::BufferLength { what: "hessian", expected, got });
        }
        Ok(())
    }

    /// The forward pass with derivatives, values (and Jacobian) read out, output adjoints
    /// seeded with the weights.
    fn forward_and_seed(
        &self,
        input: &[f64],
        weights: &[f64],
        hws: &mut HessianWorkspace,
        values: &mut [f64],
        jacobian: Option<&mut [f64]>,
    ) -> Result<(), SymbolicError> {
        self.check(input, &hws.fwd, values, jacobian.as_deref().map(<[f64]>::len))?;
        if self.dense {
            self.tape.run_dense(input, &self.param_values, &mut hws.fwd, true);
        } else {
            self.tape.run(input, &self.param_values, &mut hws.fwd, true);
        }
        self.read_values(&hws.fwd, values);
        if let Some(jac) = jacobian {
            self.read_jacobian(&hws.fwd, jac, None);
        }
        hws.so.adj.fill(0.0);
        for (a, &w) in self.outputs.iter().zip(weights) {
            if let Arg::Slot(s) = *a {
                hws.so.adj[s as usize] += w;
            }
        }
        Ok(())
    }

    fn dense_sweep(&self, fwd: &mut Workspace, so: &mut SecondOrder, h: &mut [f64]) {
        let t = &self.tape;
        match t.dense_stride() {
            4 => reverse(t, fwd, so, &mut DenseSquare::<4> { h }),
            8 => reverse(t, fwd, so, &mut DenseSquare::<8> { h }),
            12 => reverse(t, fwd, so, &mut DenseSquare::<12> { h }),
            16 => reverse(t, fwd, so, &mut DenseSquare::<16> { h }),
            w => unreachable!("dense stride {w} beyond DENSE_MAX_INPUTS"),
        }
    }
}
