//! The flat scalar tape and its allocation-free evaluation with sparse forward-mode
//! derivatives.
//!
//! Every scalar slot `s` carries the sorted list of input columns it structurally depends on
//! (`dep_cols[dep_off[s]..dep_off[s+1]]`) and, during evaluation, the derivative of its value
//! w.r.t. exactly those columns at the same offsets in `Workspace::dval`. An instruction
//! computes its local partials and scatters `partial × d(operand)` into the output's
//! derivative through index maps computed at compile time.

use std::sync::Arc;

use armature_lie::{SE3, SO3};
use nalgebra::{Matrix3, Matrix4, Vector3, Vector6};

use crate::expr::{BinaryOp, LieOp, UnaryOp};

/// Marks a scatter map that is the identity (operand and output have the same columns).
pub(crate) const IDENTITY: u32 = u32::MAX;
/// Marks a contiguous scatter map: the operand's columns sit at `offset..offset+n` of the
/// output's (the low 31 bits hold the offset).
pub(crate) const CONTIGUOUS: u32 = 1 << 31;

/// An operand during lowering: a compile-time constant or a slot. On the tape every operand
/// is a slot; constants get slots preset once in the workspace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Arg {
    Const(f64),
    Slot(u32),
}

/// Reductions over many operands with one output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Reduce {
    Norm2,
    MaxAbs,
}

/// One tape instruction. Operands are slots; `mx`/`my`/`maps` encode how operand derivative
/// columns scatter into the output's (see [`IDENTITY`], [`CONTIGUOUS`]).
#[derive(Debug, Clone)]
pub(crate) enum Instr {
    Input {
        out: u32,
        index: u32,
    },
    Param {
        out: u32,
        index: u32,
    },
    Unary {
        op: UnaryOp,
        x: u32,
        out: u32,
    },
    /// `out = sin x`, `out + 1 = cos x`, with one `sin_cos` call.
    SinCos {
        x: u32,
        out: u32,
    },
    Add {
        x: u32,
        y: u32,
        out: u32,
        mx: u32,
        my: u32,
    },
    Sub {
        x: u32,
        y: u32,
        out: u32,
        mx: u32,
        my: u32,
    },
    Mul {
        x: u32,
        y: u32,
        out: u32,
        mx: u32,
        my: u32,
    },
    /// Division, max and min (rarer; one more dispatch on `op`).
    Binary {
        op: BinaryOp,
        x: u32,
        y: u32,
        out: u32,
        mx: u32,
        my: u32,
    },
    /// `args[a0..a0+n]`, maps of the operands consecutively from `maps`.
    Reduce {
        op: Reduce,
        a0: u32,
        n: u32,
        out: u32,
        maps: u32,
    },
    /// Outputs `out..out+nout`, all with the same columns.
    Lie {
        op: LieOp,
        a0: u32,
        n: u32,
        out: u32,
        nout: u32,
        maps: u32,
    },
    Vmap {
        body: u32,
        a0: u32,
        n: u32,
        out: u32,
        nout: u32,
        maps: u32,
    },
    /// A user function; outputs `out..out+nout`, local Jacobian into scratch like `Lie`.
    External {
        func: u32,
        a0: u32,
        n: u32,
        out: u32,
        nout: u32,
        maps: u32,
    },
}

/// A compiled vmap body: a tape whose inputs are the captured outer values and whose
/// parameters are the row.
#[derive(Debug, Clone)]
pub(crate) struct VmapBody {
    pub(crate) tape: Tape,
    pub(crate) output: Arg,
    pub(crate) batch: Arc<[f64]>,
    pub(crate) cols: usize,
}

#[derive(Debug, Clone, Default)]
pub(crate) struct Tape {
    pub(crate) instrs: Vec<Instr>,
    pub(crate) args: Vec<u32>,
    /// Constant slots and their values, written once when a workspace is created.
    pub(crate) consts: Vec<(u32, f64)>,
    pub(crate) maps: Vec<u32>,
    pub(crate) dep_off: Vec<u32>,
    pub(crate) dep_cols: Vec<u32>,
    pub(crate) vmaps: Vec<VmapBody>,
    pub(crate) externals: Vec<std::sync::Arc<dyn crate::expr::ExternalFunction>>,
    pub(crate) n_inputs: usize,
    /// Unique per compilation: a workspace holds this tape's constants and input rows, so it
    /// must not be used with another tape.
    pub(crate) id: u64,
}

/// Scratch memory for evaluating a compiled [`Function`](crate::Function); create it once
/// with [`Function::workspace`](crate::Function::workspace) and reuse it.
#[derive(Debug, Clone)]
pub struct Workspace {
    pub(crate) tape_id: u64,
    pub(crate) val: Vec<f64>,
    pub(crate) dval: Vec<f64>,
    pub(crate) scratch: Vec<f64>,
    pub(crate) sub: Vec<Workspace>,
    /// Per slot, whether a pruned evaluation propagates its derivative
    /// ([`Tape::run_pruned`]).
    pub(crate) active: Vec<bool>,
}

impl Tape {
    pub(crate) fn n_slots(&self) -> usize {
        self.dep_off.len() - 1
    }

    pub(crate) fn deps(&self, slot: u32) -> &[u32] {
        &self.dep_cols
            [self.dep_off[slot as usize] as usize..self.dep_off[slot as usize + 1] as usize]
    }

    pub(crate) fn workspace(&self) -> Workspace {
        // Scratch holds a local Jacobian (nout × n) plus operands and values, or a vmap's 2n
        // values.
        let scratch_len = self
            .instrs
            .iter()
            .map(|i| match i {
                Instr::Reduce { n, .. } | Instr::Vmap { n, .. } => 2 * *n as usize,
                Instr::Lie { n, nout, .. } | Instr::External { n, nout, .. } => {
                    (*n as usize + 1) * (*nout as usize + 1)
                }
                _ => 0,
            })
            .max()
            .unwrap_or(0);
        let mut val = vec![0.0; self.n_slots()];
        for &(slot, c) in &self.consts {
            val[slot as usize] = c;
        }
        Workspace {
            tape_id: self.id,
            val,
            dval: vec![0.0; self.dep_cols.len()],
            scratch: vec![0.0; scratch_len + 256],
            sub: self.vmaps.iter().map(|v| v.tape.workspace()).collect(),
            active: vec![false; self.n_slots()],
        }
    }

    /// Evaluates every slot; with `jac`, also the sparse derivatives.
    pub(crate) fn run(&self, input: &[f64], params: &[f64], ws: &mut Workspace, jac: bool) {
        let off = &self.dep_off;
        for ins in &self.instrs {
            match *ins {
                Instr::Input { out, index } => {
                    ws.val[out as usize] = input[index as usize];
                    if jac {
                        ws.dval[off[out as usize] as usize] = 1.0;
                    }
                }
                Instr::Param { out, index } => ws.val[out as usize] = params[index as usize],
                Instr::Unary { op, x, out } => {
                    let (v, p) = op.eval(ws.val[x as usize]);
                    ws.val[out as usize] = v;
                    if jac {
                        self.scale(ws, x, out, p);
                    }
                }
                Instr::SinCos { x, out } => {
                    let (s, c) = ws.val[x as usize].sin_cos();
                    ws.val[out as usize] = s;
                    ws.val[out as usize + 1] = c;
                    if jac {
                        self.scale(ws, x, out, c);
                        self.scale(ws, x, out + 1, -s);
                    }
                }
                Instr::Add { x, y, out, mx, my } => {
                    ws.val[out as usize] = ws.val[x as usize] + ws.val[y as usize];
                    if jac {
                        self.binary_derivative(ws, x, y, out, mx, my, 1.0, 1.0);
                    }
                }
                Instr::Sub { x, y, out, mx, my } => {
                    ws.val[out as usize] = ws.val[x as usize] - ws.val[y as usize];
                    if jac {
                        self.binary_derivative(ws, x, y, out, mx, my, 1.0, -1.0);
                    }
                }
                Instr::Mul { x, y, out, mx, my } => {
                    let (a, b) = (ws.val[x as usize], ws.val[y as usize]);
                    ws.val[out as usize] = a * b;
                    if jac {
                        self.binary_derivative(ws, x, y, out, mx, my, b, a);
                    }
                }
                Instr::Binary { op, x, y, out, mx, my } => {
                    let (a, b) = (ws.val[x as usize], ws.val[y as usize]);
                    let (v, pa, pb) = op.eval(a, b);
                    ws.val[out as usize] = v;
                    if jac {
                        self.binary_derivative(ws, x, y, out, mx, my, pa, pb);
                    }
                }
                Instr::Reduce { op, a0, n, out, maps } => {
                    let args = &self.args[a0 as usize..(a0 + n) as usize];
                    let value = reduce_value(op, args, &ws.val, &mut ws.scratch);
                    ws.val[out as usize] = value;
                    if jac {
                        self.scatter_multi(ws, a0, n, out, 1, maps);
                    }
                }
                Instr::Lie { op, a0, n, out, nout, maps } => {
                    self.eval_lie(op, a0, n, out, nout, ws);
                    if jac {
                        self.scatter_multi(ws, a0, n, out, nout, maps);
                    }
                }
                Instr::Vmap { body, a0, n, out, nout, maps } => {
                    self.eval_vmap(body, a0, n, out, nout, maps, ws, jac);
                }
                Instr::External { func, a0, n, out, nout, maps } => {
                    self.eval_external(func, a0, n, out, nout, ws);
                    if jac {
                        self.scatter_multi(ws, a0, n, out, nout, maps);
                    }
                }
            }
        }
    }

    /// Values of every slot, then derivatives only where they can reach a slot marked in
    /// `ws.active` (the caller marks the output slots it needs): a slot's derivative is
    /// propagated when some consumer on such a path has a nonzero local partial with respect
    /// to it. An inactive ReLU (`pos`, `sqpos` at x ≤ 0), the unselected operand of `max` /
    /// `min` and a factor multiplied by an exact zero cut the paths through them. The needed
    /// slots get exactly the derivatives [`run`](Self::run) computes (a cut path contributes
    /// partial × derivative = 0 there); the others are not computed.
    pub(crate) fn run_pruned(&self, input: &[f64], params: &[f64], ws: &mut Workspace) {
        self.run(input, params, ws, false);
        self.mark_active(ws);
        self.derivatives(ws);
    }

    /// Backward pass of [`run_pruned`](Self::run_pruned): from the marked outputs, marks the
    /// operands each marked instruction differentiates with a nonzero partial.
    fn mark_active(&self, ws: &mut Workspace) {
        let (val, act) = (&ws.val, &mut ws.active);
        let v = |s: u32| val[s as usize];
        for ins in self.instrs.iter().rev() {
            match *ins {
                Instr::Input { .. } | Instr::Param { .. } => {}
                Instr::Unary { op, x, out } => {
                    if act[out as usize] && !unary_partial_is_zero(op, v(x)) {
                        act[x as usize] = true;
                    }
                }
                Instr::SinCos { x, out } => {
                    if act[out as usize] || act[out as usize + 1] {
                        act[x as usize] = true;
                    }
                }
                Instr::Add { x, y, out, .. } | Instr::Sub { x, y, out, .. } => {
                    if act[out as usize] {
                        act[x as usize] = true;
                        act[y as usize] = true;
                    }
                }
                Instr::Mul { x, y, out, .. } => {
                    if act[out as usize] {
                        // ∂(xy)/∂x = y, ∂(xy)/∂y = x.
                        act[x as usize] |= v(y) != 0.0;
                        act[y as usize] |= v(x) != 0.0;
                    }
                }
                Instr::Binary { op, x, y, out, .. } => {
                    if act[out as usize] {
                        let (ux, uy) = binary_operands_used(op, v(x), v(y));
                        act[x as usize] |= ux;
                        act[y as usize] |= uy;
                    }
                }
                Instr::Reduce { a0, n, out, .. } => {
                    if act[out as usize] {
                        for &a in &self.args[a0 as usize..(a0 + n) as usize] {
                            act[a as usize] = true;
                        }
                    }
                }
                Instr::Lie { a0, n, out, nout, .. }
                | Instr::Vmap { a0, n, out, nout, .. }
                | Instr::External { a0, n, out, nout, .. } => {
                    if act[out as usize..(out + nout) as usize].iter().any(|&a| a) {
                        for &a in &self.args[a0 as usize..(a0 + n) as usize] {
                            act[a as usize] = true;
                        }
                    }
                }
            }
        }
    }

    /// Forward derivative pass of [`run_pruned`](Self::run_pruned) over the marked
    /// instructions (values are in place; local partials are recomputed from them).
    fn derivatives(&self, ws: &mut Workspace) {
        let off = &self.dep_off;
        for ins in &self.instrs {
            match *ins {
                Instr::Input { out, .. } => {
                    if ws.active[out as usize] {
                        ws.dval[off[out as usize] as usize] = 1.0;
                    }
                }
                Instr::Param { .. } => {}
                Instr::Unary { op, x, out } => {
                    if ws.active[out as usize] {
                        if ws.active[x as usize] {
                            let p = op.eval(ws.val[x as usize]).1;
                            self.scale(ws, x, out, p);
                        } else {
                            self.clear(ws, out);
                        }
                    }
                }
                Instr::SinCos { x, out } => {
                    if ws.active[out as usize] || ws.active[out as usize + 1] {
                        let (sn, cs) = (ws.val[out as usize], ws.val[out as usize + 1]);
                        self.scale(ws, x, out, cs);
                        self.scale(ws, x, out + 1, -sn);
                    }
                }
                Instr::Add { x, y, out, mx, my } => {
                    if ws.active[out as usize] {
                        self.binary_derivative(ws, x, y, out, mx, my, 1.0, 1.0);
                    }
                }
                Instr::Sub { x, y, out, mx, my } => {
                    if ws.active[out as usize] {
                        self.binary_derivative(ws, x, y, out, mx, my, 1.0, -1.0);
                    }
                }
                Instr::Mul { x, y, out, mx, my } => {
                    if ws.active[out as usize] {
                        let (a, b) = (ws.val[x as usize], ws.val[y as usize]);
                        self.clear_inactive(ws, x);
                        self.clear_inactive(ws, y);
                        self.binary_derivative(ws, x, y, out, mx, my, b, a);
                    }
                }
                Instr::Binary { op, x, y, out, mx, my } => {
                    if ws.active[out as usize] {
                        let (_, pa, pb) = op.eval(ws.val[x as usize], ws.val[y as usize]);
                        self.clear_inactive(ws, x);
                        self.clear_inactive(ws, y);
                        self.binary_derivative(ws, x, y, out, mx, my, pa, pb);
                    }
                }
                Instr::Reduce { op, a0, n, out, maps } => {
                    if ws.active[out as usize] {
                        let args = &self.args[a0 as usize..(a0 + n) as usize];
                        reduce_value(op, args, &ws.val, &mut ws.scratch);
                        self.scatter_multi(ws, a0, n, out, 1, maps);
                    }
                }
                Instr::Lie { op, a0, n, out, nout, maps } => {
                    if ws.active[out as usize..(out + nout) as usize].iter().any(|&a| a) {
                        self.eval_lie(op, a0, n, out, nout, ws);
                        self.scatter_multi(ws, a0, n, out, nout, maps);
                    }
                }
                Instr::Vmap { body, a0, n, out, nout, maps } => {
                    if ws.active[out as usize..(out + nout) as usize].iter().any(|&a| a) {
                        self.eval_vmap(body, a0, n, out, nout, maps, ws, true);
                    }
                }
                Instr::External { func, a0, n, out, nout, maps } => {
                    if ws.active[out as usize..(out + nout) as usize].iter().any(|&a| a) {
                        self.eval_external(func, a0, n, out, nout, ws);
                        self.scatter_multi(ws, a0, n, out, nout, maps);
                    }
                }
            }
        }
    }

    /// Zero derivative of `slot`.
    fn clear(&self, ws: &mut Workspace, slot: u32) {
        let (o, n) = self.range(slot);
        ws.dval[o..o + n].fill(0.0);
    }

    /// Zero derivative of an operand the pruned pass did not differentiate (its partial is
    /// zero; the stale value it holds must not reach the product).
    fn clear_inactive(&self, ws: &mut Workspace, slot: u32) {
        if !ws.active[slot as usize] {
            self.clear(ws, slot);
        }
    }

    /// Runs a user function: operands gathered after the local Jacobian in scratch, values
    /// into the output slots, Jacobian into `scratch[0..nout·n]`.
    pub(crate) fn eval_external(
        &self,
        func: u32,
        a0: u32,
        n: u32,
        out: u32,
        nout: u32,
        ws: &mut Workspace,
    ) {
        let (n, m) = (n as usize, nout as usize);
        let (jac, rest) = ws.scratch.split_at_mut(m * n);
        let (inputs, values) = rest.split_at_mut(n);
        for k in 0..n {
            inputs[k] = ws.val[self.args[a0 as usize + k] as usize];
        }
        self.externals[func as usize].eval(inputs, &mut values[..m], jac);
        ws.val[out as usize..out as usize + m].copy_from_slice(&values[..m]);
    }

    /// Row stride of dense mode: the input count rounded up to a multiple of 4 (≤ 16), so
    /// each derivative update is a few full-width SIMD operations.
    pub(crate) fn dense_stride(&self) -> usize {
        self.n_inputs.div_ceil(4).max(1) * 4
    }

    /// Like [`run`](Self::run) with dense derivative rows: `dval[s·N..(s+1)·N]` is the full
    /// gradient of slot `s` (padded to the stride `N`). Branch-free and vectorisable, it beats
    /// the sparse bookkeeping when there are few inputs. Input rows (unit vectors) and
    /// constant rows (zero) are preset by [`workspace_dense`](Self::workspace_dense).
    pub(crate) fn run_dense(&self, input: &[f64], params: &[f64], ws: &mut Workspace, jac: bool) {
        match self.dense_stride() {
            4 => self.run_dense_n::<4>(input, params, ws, jac),
            8 => self.run_dense_n::<8>(input, params, ws, jac),
            12 => self.run_dense_n::<12>(input, params, ws, jac),
            16 => self.run_dense_n::<16>(input, params, ws, jac),
            w => unreachable!("dense stride {w} beyond DENSE_MAX_INPUTS"),
        }
    }

    fn run_dense_n<const N: usize>(
        &self,
        input: &[f64],
        params: &[f64],
        ws: &mut Workspace,
        jac: bool,
    ) {
        /// (rows before `out`, the row of `out`).
        #[inline(always)]
        fn split<const N: usize>(dval: &mut [f64], out: u32) -> (&[f64], &mut [f64; N]) {
            let (before, rest) = dval.split_at_mut(out as usize * N);
            (before, (&mut rest[..N]).try_into().expect("row of N"))
        }
        #[inline(always)]
        fn row<const N: usize>(before: &[f64], s: u32) -> &[f64; N] {
            before[s as usize * N..s as usize * N + N].try_into().expect("row of N")
        }
        #[inline(always)]
        fn lin2<const N: usize>(dval: &mut [f64], x: u32, y: u32, out: u32, pa: f64, pb: f64) {
            let (b, d) = split::<N>(dval, out);
            let (dx, dy) = (row::<N>(b, x), row::<N>(b, y));
            for j in 0..N {
                d[j] = pa * dx[j] + pb * dy[j];
            }
        }
        for ins in &self.instrs {
            match *ins {
                Instr::Input { out, index } => ws.val[out as usize] = input[index as usize],
                Instr::Param { out, index } => ws.val[out as usize] = params[index as usize],
                Instr::Unary { op, x, out } => {
                    let (v, p) = op.eval(ws.val[x as usize]);
                    ws.val[out as usize] = v;
                    if jac {
                        let (b, d) = split::<N>(&mut ws.dval, out);
                        let dx = row::<N>(b, x);
                        for j in 0..N {
                            d[j] = p * dx[j];
                        }
                    }
                }
                Instr::SinCos { x, out } => {
                    let (sn, cs) = ws.val[x as usize].sin_cos();
                    ws.val[out as usize] = sn;
                    ws.val[out as usize + 1] = cs;
                    if jac {
                        let (b, rest) = ws.dval.split_at_mut(out as usize * N);
                        let dx = row::<N>(b, x);
                        let (ds, dc) = rest[..2 * N].split_at_mut(N);
                        for j in 0..N {
                            ds[j] = cs * dx[j];
                            dc[j] = -sn * dx[j];
                        }
                    }
                }
                Instr::Add { x, y, out, .. } => {
                    ws.val[out as usize] = ws.val[x as usize] + ws.val[y as usize];
                    if jac {
                        lin2::<N>(&mut ws.dval, x, y, out, 1.0, 1.0);
                    }
                }
                Instr::Sub { x, y, out, .. } => {
                    ws.val[out as usize] = ws.val[x as usize] - ws.val[y as usize];
                    if jac {
                        lin2::<N>(&mut ws.dval, x, y, out, 1.0, -1.0);
                    }
                }
                Instr::Mul { x, y, out, .. } => {
                    let (a, b) = (ws.val[x as usize], ws.val[y as usize]);
                    ws.val[out as usize] = a * b;
                    if jac {
                        lin2::<N>(&mut ws.dval, x, y, out, b, a);
                    }
                }
                Instr::Binary { op, x, y, out, .. } => {
                    let (v, pa, pb) = op.eval(ws.val[x as usize], ws.val[y as usize]);
                    ws.val[out as usize] = v;
                    if jac {
                        lin2::<N>(&mut ws.dval, x, y, out, pa, pb);
                    }
                }
                Instr::Reduce { op, a0, n, out, .. } => {
                    let args = &self.args[a0 as usize..(a0 + n) as usize];
                    ws.val[out as usize] = reduce_value(op, args, &ws.val, &mut ws.scratch);
                    if jac {
                        self.dense_multi::<N>(ws, a0, n, out, 1);
                    }
                }
                Instr::Lie { op, a0, n, out, nout, .. } => {
                    self.eval_lie(op, a0, n, out, nout, ws);
                    if jac {
                        self.dense_multi::<N>(ws, a0, n, out, nout);
                    }
                }
                Instr::External { func, a0, n, out, nout, .. } => {
                    self.eval_external(func, a0, n, out, nout, ws);
                    if jac {
                        self.dense_multi::<N>(ws, a0, n, out, nout);
                    }
                }
                Instr::Vmap { .. } => {
                    unreachable!("functions with vmaps are compiled in sparse mode")
                }
            }
        }
    }

    /// Dense rows of outputs `out..out+nout` from the local Jacobian in `scratch[o·n + k]`.
    fn dense_multi<const N: usize>(
        &self,
        ws: &mut Workspace,
        a0: u32,
        n: u32,
        out: u32,
        nout: u32,
    ) {
        for o in 0..nout as usize {
            let (b, rest) = ws.dval.split_at_mut((out as usize + o) * N);
            let d = &mut rest[..N];
            d.fill(0.0);
            for k in 0..n as usize {
                let p = ws.scratch[o * n as usize + k];
                let a = self.args[a0 as usize + k] as usize;
                if p != 0.0 {
                    for (dj, xj) in d.iter_mut().zip(&b[a * N..a * N + N]) {
                        *dj += p * xj;
                    }
                }
            }
        }
    }

    #[inline(always)]
    pub(crate) fn range(&self, s: u32) -> (usize, usize) {
        let o = self.dep_off[s as usize] as usize;
        (o, self.dep_off[s as usize + 1] as usize - o)
    }

    /// `d(out) = p · d(x)` where `out` has the columns of `x`.
    #[inline(always)]
    fn scale(&self, ws: &mut Workspace, x: u32, out: u32, p: f64) {
        let (xo, n) = self.range(x);
        let oo = self.dep_off[out as usize] as usize;
        let (src, dst) = if xo + n <= oo {
            let (a, b) = ws.dval.split_at_mut(oo);
            (&a[xo..xo + n], &mut b[..n])
        } else {
            unreachable_order()
        };
        for (d, s) in dst.iter_mut().zip(src) {
            *d = p * s;
        }
    }

    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn binary_derivative(
        &self,
        ws: &mut Workspace,
        x: u32,
        y: u32,
        out: u32,
        mx: u32,
        my: u32,
        pa: f64,
        pb: f64,
    ) {
        let (oo, n) = self.range(out);
        let (xo, nx) = self.range(x);
        let (yo, ny) = self.range(y);
        let x_covers = mx == IDENTITY && nx == n;
        let y_covers = my == IDENTITY && ny == n;
        // Operands always precede the output on the tape, so their derivatives lie before it.
        let (before, dst) = ws.dval.split_at_mut(oo);
        let dst = &mut dst[..n];
        match (x_covers, y_covers) {
            (true, true) => {
                let (dx, dy) = (&before[xo..xo + n], &before[yo..yo + n]);
                for j in 0..n {
                    dst[j] = pa * dx[j] + pb * dy[j];
                }
            }
            (true, false) => {
                for (d, s) in dst.iter_mut().zip(&before[xo..xo + n]) {
                    *d = pa * s;
                }
                self.scatter(before, yo, ny, dst, my, pb);
            }
            (false, true) => {
                for (d, s) in dst.iter_mut().zip(&before[yo..yo + n]) {
                    *d = pb * s;
                }
                self.scatter(before, xo, nx, dst, mx, pa);
            }
            (false, false) => {
                dst.fill(0.0);
                self.scatter(before, xo, nx, dst, mx, pa);
                self.scatter(before, yo, ny, dst, my, pb);
            }
        }
    }

    /// `dst[map(j)] += p · src[so + j]` for `j < n`.
    #[inline(always)]
    fn scatter(&self, src: &[f64], so: usize, n: usize, dst: &mut [f64], map: u32, p: f64) {
        if n == 0 || p == 0.0 {
            return;
        }
        let s = &src[so..so + n];
        if map == IDENTITY {
            for (d, v) in dst[..n].iter_mut().zip(s) {
                *d += p * v;
            }
        } else if map & CONTIGUOUS != 0 {
            let o = (map & !CONTIGUOUS) as usize;
            for (d, v) in dst[o..o + n].iter_mut().zip(s) {
                *d += p * v;
            }
        } else {
            let m = &self.maps[map as usize..map as usize + n];
            for (&k, v) in m.iter().zip(s) {
                dst[k as usize] += p * v;
            }
        }
    }

    /// Derivatives of outputs `out..out+nout` from the dense local Jacobian in
    /// `scratch[o·n + k]` (row per output) and the operands' derivatives.
    fn scatter_multi(&self, ws: &mut Workspace, a0: u32, n: u32, out: u32, nout: u32, maps: u32) {
        for o in 0..nout as usize {
            let (oo, no) = self.range(out + o as u32);
            let (before, dst) = ws.dval.split_at_mut(oo);
            let dst = &mut dst[..no];
            dst.fill(0.0);
            let mut m = maps as usize;
            for k in 0..n as usize {
                let s = self.args[a0 as usize + k];
                let (so, ns) = self.range(s);
                if ns > 0 {
                    let p = ws.scratch[o * n as usize + k];
                    self.scatter(before, so, ns, dst, m as u32, p);
                    m += ns;
                }
            }
        }
    }

    /// Values of a Lie node into its output slots and its local Jacobian (row per output)
    /// into `scratch[0..nout·n]`.
    pub(crate) fn eval_lie(
        &self,
        op: LieOp,
        a0: u32,
        n: u32,
        out: u32,
        nout: u32,
        ws: &mut Workspace,
    ) {
        let args = &self.args[a0 as usize..(a0 + n) as usize];
        let x = |k: usize| ws.val[args[k] as usize];
        let n = n as usize;
        let mut outv = [0.0; 12];
        let mut local = [0.0; 72];
        match op {
            LieOp::So3Exp => {
                let w = Vector3::new(x(0), x(1), x(2));
                let r = SO3::exp(&w).matrix();
                let d = SO3::dexp_dtangent_matrix(&w);
                for e in 0..9 {
                    outv[e] = r[(e / 3, e % 3)];
                    for j in 0..3 {
                        local[e * n + j] = d[j][(e / 3, e % 3)];
                    }
                }
            }
            LieOp::Se3Exp => {
                let xi = Vector6::from_fn(|i, _| x(i));
                let t = SE3::exp(&xi).matrix();
                let d = SE3::dexp_dtangent_matrix(&xi);
                for e in 0..12 {
                    outv[e] = t[(e / 4, e % 4)];
                    for j in 0..6 {
                        local[e * n + j] = d[j][(e / 4, e % 4)];
                    }
                }
            }
            LieOp::So3Log => {
                let m = Matrix3::from_fn(|r, c| x(r * 3 + c));
                let rot = SO3::from_matrix_unchecked(&m);
                let w = rot.log();
                let g = rot.dlog_dmatrix();
                for i in 0..3 {
                    outv[i] = w[i];
                    for e in 0..9 {
                        local[i * n + e] = g[i][(e / 3, e % 3)];
                    }
                }
            }
            LieOp::Se3Log => {
                // Operands are the 12 entries of the top three rows.
                let mut m = Matrix4::identity();
                for e in 0..12 {
                    m[(e / 4, e % 4)] = x(e);
                }
                let rot = SO3::from_matrix_unchecked(&m.fixed_view::<3, 3>(0, 0).into_owned());
                let t = SE3::from_parts(rot, Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]));
                let xi = t.log();
                let g = t.dlog_dmatrix();
                for i in 0..6 {
                    outv[i] = xi[i];
                    for e in 0..12 {
                        local[i * n + e] = g[i][(e / 4, e % 4)];
                    }
                }
            }
        }
        for o in 0..nout as usize {
            ws.val[out as usize + o] = outv[o];
        }
        ws.scratch[..nout as usize * n].copy_from_slice(&local[..nout as usize * n]);
    }

    #[allow(clippy::too_many_arguments)]
    fn eval_vmap(
        &self,
        body: u32,
        a0: u32,
        n: u32,
        out: u32,
        nout: u32,
        maps: u32,
        ws: &mut Workspace,
        jac: bool,
    ) {
        let vb = &self.vmaps[body as usize];
        let n = n as usize;
        let mut sub = std::mem::replace(&mut ws.sub[body as usize], Workspace::empty());
        // Captured values are the body's inputs: scratch[n..2n]; its gradient: scratch[0..n].
        for k in 0..n {
            ws.scratch[n + k] = ws.val[self.args[a0 as usize + k] as usize];
        }
        for r in 0..nout as usize {
            let row = &vb.batch[r * vb.cols..(r + 1) * vb.cols];
            vb.tape.run(&ws.scratch[n..2 * n], row, &mut sub, jac);
            let os = out + r as u32;
            ws.val[os as usize] = match vb.output {
                Arg::Const(c) => c,
                Arg::Slot(s) => sub.val[s as usize],
            };
            if jac {
                ws.scratch[..n].fill(0.0);
                if let Arg::Slot(s) = vb.output {
                    let (so, _) = vb.tape.range(s);
                    for (j, &c) in vb.tape.deps(s).iter().enumerate() {
                        ws.scratch[c as usize] = sub.dval[so + j];
                    }
                }
                let (oo, no) = self.range(os);
                let (before, dst) = ws.dval.split_at_mut(oo);
                let dst = &mut dst[..no];
                dst.fill(0.0);
                let mut m = maps as usize;
                for k in 0..n {
                    let (so, ns) = self.range(self.args[a0 as usize + k]);
                    if ns > 0 {
                        self.scatter(before, so, ns, dst, m as u32, ws.scratch[k]);
                        m += ns;
                    }
                }
            }
        }
        ws.sub[body as usize] = sub;
    }
}

/// Whether `op`'s derivative at `x` is exactly zero for a reason a pruned evaluation can
/// use (an inactive ReLU), matching [`UnaryOp::eval`].
fn unary_partial_is_zero(op: UnaryOp, x: f64) -> bool {
    // `x > 0` is false for NaN too, as in `eval`.
    let positive = x > 0.0;
    matches!(op, UnaryOp::Pos | UnaryOp::SquaredPos) && !positive
}

/// Which operands of `op` at `(x, y)` have a partial that may be nonzero (the selected one of
/// `max` / `min`, matching [`BinaryOp::eval`]; both otherwise).
fn binary_operands_used(op: BinaryOp, x: f64, y: f64) -> (bool, bool) {
    // The comparisons `eval` makes (false with a NaN, which then selects y).
    let selects_x = match op {
        BinaryOp::Max => x >= y,
        BinaryOp::Min => x <= y,
        _ => return (true, true),
    };
    (selects_x, !selects_x)
}

/// Value of a reduction, and its partials into `partials[0..args.len()]`.
pub(crate) fn reduce_value(op: Reduce, args: &[u32], val: &[f64], partials: &mut [f64]) -> f64 {
    match op {
        Reduce::Norm2 => {
            let s: f64 = args.iter().map(|&a| val[a as usize].powi(2)).sum();
            let nrm = s.sqrt();
            for (k, &a) in args.iter().enumerate() {
                partials[k] = if nrm > 0.0 { val[a as usize] / nrm } else { 0.0 };
            }
            nrm
        }
        Reduce::MaxAbs => {
            let (mut best, mut arg) = (f64::NEG_INFINITY, 0);
            for (k, &a) in args.iter().enumerate() {
                let x = val[a as usize].abs();
                if x > best {
                    (best, arg) = (x, k);
                }
                partials[k] = 0.0;
            }
            let x = val[args[arg] as usize];
            partials[arg] = if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                0.0
            };
            best
        }
    }
}

#[cold]
fn unreachable_order() -> ! {
    unreachable!("tape operands always precede their outputs")
}

impl Tape {
    /// A workspace for [`run_dense`](Self::run_dense): dense rows, input rows preset to unit
    /// vectors, constant rows zero.
    pub(crate) fn workspace_dense(&self) -> Workspace {
        let mut ws = self.workspace();
        let w = self.dense_stride();
        ws.dval = vec![0.0; self.n_slots() * w];
        for ins in &self.instrs {
            if let Instr::Input { out, index } = *ins {
                ws.dval[out as usize * w + index as usize] = 1.0;
            }
        }
        ws
    }
}

impl Workspace {
    fn empty() -> Self {
        Workspace {
            tape_id: 0,
            val: Vec::new(),
            dval: Vec::new(),
            scratch: Vec::new(),
            sub: Vec::new(),
            active: Vec::new(),
        }
    }
}
