//! The second-order reverse sweep.
//!
//! After a forward pass has left every slot's value and gradient `g_s = ∂v_s/∂x` in the
//! workspace, one backward pass carries the adjoints `ā_s = ∂(wᵀf)/∂v_s` and, at each
//! nonlinear instruction `v = φ(u₁…u_k)`, adds its curvature
//! `ā_v Σ_jk ∂²φ/∂u_j∂u_k g_j g_kᵀ` to the Hessian. Summed over the tape this is exactly
//! `∇²(wᵀf)` (the second-order chain rule unrolled); linear instructions (add, subtract,
//! gathers) cost one adjoint update and no Hessian work, and an instruction whose adjoint
//! is zero costs nothing.

use crate::expr::{BinaryOp, LieOp, UnaryOp};
use crate::tape::{Arg, Instr, Reduce, Tape, Workspace, reduce_value};

use super::accumulate::{Accumulate, LocalSquare};
use super::lie;

/// Scratch of one sweep: adjoints, a local weighted Hessian, and per `vmap` body its own.
#[derive(Debug, Clone)]
pub(crate) struct SecondOrder {
    pub(crate) adj: Vec<f64>,
    w: Vec<f64>,
    vmaps: Vec<VmapScratch>,
}

/// A `vmap` body's forward workspace, sweep scratch, captured values and local Hessian.
#[derive(Debug, Clone)]
struct VmapScratch {
    fwd: Workspace,
    so: SecondOrder,
    inputs: Vec<f64>,
    local: Vec<f64>,
}

impl SecondOrder {
    pub(crate) fn new(tape: &Tape) -> Self {
        let widest = tape
            .instrs
            .iter()
            .map(|i| match *i {
                Instr::Lie { n, .. } | Instr::External { n, .. } => n as usize,
                _ => 0,
            })
            .max()
            .unwrap_or(0);
        let vmaps = tape
            .vmaps
            .iter()
            .map(|v| {
                let n = v.tape.n_inputs;
                VmapScratch {
                    fwd: v.tape.workspace(),
                    so: SecondOrder::new(&v.tape),
                    inputs: vec![0.0; n],
                    local: vec![0.0; n * n],
                }
            })
            .collect();
        SecondOrder { adj: vec![0.0; tape.n_slots()], w: vec![0.0; widest * widest], vmaps }
    }
}

/// `φ''(x)` of a unary operation, with the one-sided choices of its first derivative at
/// kinks (`abs`, `pos`: 0; `squared_pos` at 0: 0, its left side; `sqrt` at 0: 0).
pub(crate) fn unary_second(op: UnaryOp, x: f64) -> f64 {
    match op {
        UnaryOp::Neg | UnaryOp::Abs | UnaryOp::Pos => 0.0,
        UnaryOp::Sqrt => {
            let s = x.sqrt();
            if s > 0.0 { -0.25 / (s * x) } else { 0.0 }
        }
        UnaryOp::Square => 2.0,
        UnaryOp::Sin => -x.sin(),
        UnaryOp::Cos => -x.cos(),
        UnaryOp::Tan => {
            let t = x.tan();
            2.0 * t * (1.0 + t * t)
        }
        UnaryOp::Exp => x.exp(),
        UnaryOp::Log => -1.0 / (x * x),
        UnaryOp::Tanh => {
            let t = x.tanh();
            -2.0 * t * (1.0 - t * t)
        }
        UnaryOp::SquaredPos => {
            if x > 0.0 {
                2.0
            } else {
                0.0
            }
        }
    }
}

/// Whether `op` has a structurally nonzero second derivative.
pub(crate) fn unary_is_curved(op: UnaryOp) -> bool {
    !matches!(op, UnaryOp::Neg | UnaryOp::Abs | UnaryOp::Pos)
}

/// `Σ_jk W_jk g_j g_kᵀ` of a dense symmetric local Hessian `w` over operands `args`.
fn add_local<A: Accumulate>(acc: &mut A, tape: &Tape, ws: &Workspace, args: &[u32], w: &[f64]) {
    let n = args.len();
    for j in 0..n {
        let d = w[j * n + j];
        if d != 0.0 {
            acc.rank1(tape, ws, args[j], d);
        }
        for k in 0..j {
            let c = w[j * n + k];
            if c != 0.0 {
                acc.rank2(tape, ws, args[j], args[k], c);
            }
        }
    }
}

/// The backward pass: `so.adj` holds the output adjoints on entry (zero elsewhere); the
/// curvature goes to `acc`. `ws` holds the forward pass's values and gradients.
pub(crate) fn reverse<A: Accumulate>(
    tape: &Tape,
    ws: &mut Workspace,
    so: &mut SecondOrder,
    acc: &mut A,
) {
    let SecondOrder { adj, w, vmaps } = so;
    for ins in tape.instrs.iter().rev() {
        match *ins {
            Instr::Input { .. } | Instr::Param { .. } => {}
            Instr::Unary { op, x, out } => {
                let a = adj[out as usize];
                if a != 0.0 {
                    let xv = ws.val[x as usize];
                    adj[x as usize] += a * op.eval(xv).1;
                    let c = unary_second(op, xv);
                    if c != 0.0 {
                        acc.rank1(tape, ws, x, a * c);
                    }
                }
            }
            Instr::SinCos { x, out } => {
                let (a_s, a_c) = (adj[out as usize], adj[out as usize + 1]);
                if a_s != 0.0 || a_c != 0.0 {
                    let (s, c) = (ws.val[out as usize], ws.val[out as usize + 1]);
                    adj[x as usize] += a_s * c - a_c * s;
                    acc.rank1(tape, ws, x, -a_s * s - a_c * c);
                }
            }
            Instr::Add { x, y, out, .. } => {
                let a = adj[out as usize];
                adj[x as usize] += a;
                adj[y as usize] += a;
            }
            Instr::Sub { x, y, out, .. } => {
                let a = adj[out as usize];
                adj[x as usize] += a;
                adj[y as usize] -= a;
            }
            Instr::Mul { x, y, out, .. } => {
                let a = adj[out as usize];
                if a != 0.0 {
                    adj[x as usize] += a * ws.val[y as usize];
                    adj[y as usize] += a * ws.val[x as usize];
                    acc.rank2(tape, ws, x, y, a);
                }
            }
            Instr::Binary { op, x, y, out, .. } => {
                let a = adj[out as usize];
                if a != 0.0 {
                    let (xv, yv) = (ws.val[x as usize], ws.val[y as usize]);
                    let (_, pa, pb) = op.eval(xv, yv);
                    adj[x as usize] += a * pa;
                    adj[y as usize] += a * pb;
                    if op == BinaryOp::Div {
                        let inv = 1.0 / yv;
                        acc.rank2(tape, ws, x, y, -a * inv * inv);
                        acc.rank1(tape, ws, y, 2.0 * a * xv * inv * inv * inv);
                    }
                }
            }
            Instr::Reduce { op, a0, n, out, .. } => {
                let a = adj[out as usize];
                if a != 0.0 {
                    reduce_reverse(tape, ws, adj, acc, op, a0, n, a);
                }
            }
            Instr::Lie { op, a0, n, out, nout, .. } => {
                let wts = &adj[out as usize..(out + nout) as usize];
                if wts.iter().any(|&v| v != 0.0) {
                    lie_reverse(tape, ws, adj, w, acc, op, a0, n, out, nout);
                }
            }
            Instr::External { func, a0, n, out, nout, .. } => {
                let wts = &adj[out as usize..(out + nout) as usize];
                if wts.iter().any(|&v| v != 0.0) {
                    external_reverse(tape, ws, adj, w, acc, func, a0, n, out, nout);
                }
            }
            Instr::Vmap { body, a0, n, out, nout, .. } => {
                let wts = &adj[out as usize..(out + nout) as usize];
                if wts.iter().any(|&v| v != 0.0) {
                    vmap_reverse(
                        tape,
                        ws,
                        adj,
                        &mut vmaps[body as usize],
                        acc,
                        body,
                        a0,
                        n,
                        out,
                        nout,
                    );
                }
            }
        }
    }
}

/// `‖u‖₂`: gradient `u/‖u‖`, Hessian `(I − ûûᵀ)/‖u‖` (0 at the origin, where the gradient
/// is taken as 0 too); `max|u|` is piecewise linear.
#[allow(clippy::too_many_arguments)]
fn reduce_reverse<A: Accumulate>(
    tape: &Tape,
    ws: &mut Workspace,
    adj: &mut [f64],
    acc: &mut A,
    op: Reduce,
    a0: u32,
    n: u32,
    a: f64,
) {
    let args = &tape.args[a0 as usize..(a0 + n) as usize];
    let value = reduce_value(op, args, &ws.val, &mut ws.scratch);
    for (k, &s) in args.iter().enumerate() {
        adj[s as usize] += a * ws.scratch[k];
    }
    if op != Reduce::Norm2 || value <= 0.0 {
        return;
    }
    let c = a / value;
    for j in 0..args.len() {
        let uj = ws.scratch[j];
        acc.rank1(tape, ws, args[j], c * (1.0 - uj * uj));
        for k in 0..j {
            acc.rank2(tape, ws, args[j], args[k], -c * uj * ws.scratch[k]);
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn lie_reverse<A: Accumulate>(
    tape: &Tape,
    ws: &mut Workspace,
    adj: &mut [f64],
    w: &mut [f64],
    acc: &mut A,
    op: LieOp,
    a0: u32,
    n: u32,
    out: u32,
    nout: u32,
) {
    tape.eval_lie(op, a0, n, out, nout, ws);
    let args = &tape.args[a0 as usize..(a0 + n) as usize];
    let (n, m) = (n as usize, nout as usize);
    let mut x = [0.0; 12];
    let mut wts = [0.0; 12];
    for k in 0..n {
        x[k] = ws.val[args[k] as usize];
    }
    wts[..m].copy_from_slice(&adj[out as usize..out as usize + m]);
    let local = &ws.scratch[..m * n];
    for (k, &s) in args.iter().enumerate() {
        adj[s as usize] += (0..m).map(|o| wts[o] * local[o * n + k]).sum::<f64>();
    }
    let w = &mut w[..n * n];
    match op {
        LieOp::So3Exp => lie::so3_exp([x[0], x[1], x[2]], &wts[..m], w),
        LieOp::Se3Exp => lie::se3_exp(core::array::from_fn(|i| x[i]), &wts[..m], w),
        LieOp::So3Log => lie::so3_log(&x[..9], local, &wts[..m], w),
        LieOp::Se3Log => lie::se3_log(&x[..12], local, &wts[..m], w),
    }
    add_local(acc, tape, ws, args, w);
}

#[allow(clippy::too_many_arguments)]
fn external_reverse<A: Accumulate>(
    tape: &Tape,
    ws: &mut Workspace,
    adj: &mut [f64],
    w: &mut [f64],
    acc: &mut A,
    func: u32,
    a0: u32,
    n: u32,
    out: u32,
    nout: u32,
) {
    tape.eval_external(func, a0, n, out, nout, ws);
    let args = &tape.args[a0 as usize..(a0 + n) as usize];
    let (n, m) = (n as usize, nout as usize);
    let o0 = out as usize;
    for k in 0..n {
        // Operands precede the outputs on the tape: the outputs' adjoints are not written.
        let g: f64 = (0..m).map(|o| adj[o0 + o] * ws.scratch[o * n + k]).sum();
        adj[args[k] as usize] += g;
    }
    let ext = &tape.externals[func as usize];
    if ext.has_hessian() {
        let w = &mut w[..n * n];
        w.fill(0.0);
        let wts = &adj[out as usize..out as usize + m];
        ext.hessian(&ws.scratch[m * n..m * n + n], wts, w);
        add_local(acc, tape, ws, args, w);
    }
}

/// Per row with a nonzero adjoint: the body's forward pass again, its gradient into the
/// operands' adjoints, and its own second-order sweep into a local `n × n` Hessian, which
/// is then contracted with the operands' gradients once.
#[allow(clippy::too_many_arguments)]
fn vmap_reverse<A: Accumulate>(
    tape: &Tape,
    ws: &mut Workspace,
    adj: &mut [f64],
    vs: &mut VmapScratch,
    acc: &mut A,
    body: u32,
    a0: u32,
    n: u32,
    out: u32,
    nout: u32,
) {
    let vb = &tape.vmaps[body as usize];
    let args = &tape.args[a0 as usize..(a0 + n) as usize];
    let n = n as usize;
    let VmapScratch { fwd, so, inputs, local } = vs;
    for k in 0..n {
        inputs[k] = ws.val[args[k] as usize];
    }
    local.fill(0.0);
    let Arg::Slot(s) = vb.output else { return };
    for r in 0..nout as usize {
        let a = adj[out as usize + r];
        if a == 0.0 {
            continue;
        }
        let row = &vb.batch[r * vb.cols..(r + 1) * vb.cols];
        vb.tape.run(inputs, row, fwd, true);
        let (so_off, _) = vb.tape.range(s);
        for (j, &c) in vb.tape.deps(s).iter().enumerate() {
            adj[args[c as usize] as usize] += a * fwd.dval[so_off + j];
        }
        so.adj.fill(0.0);
        so.adj[s as usize] = a;
        reverse(&vb.tape, fwd, so, &mut LocalSquare { n, h: local });
    }
    add_local(acc, tape, ws, args, local);
}
