//! Lowering of the expression graph to the scalar tape: constant folding, structural CSE
//! (hash-consing of scalar instructions), exact dependency sets, and the product-of-
//! exponentials fast path for `se3_exp(constant_screw * angle)`.

use std::collections::HashMap;
use std::sync::Arc;

use armature_lie::{SE3, SO3};
use nalgebra::{Matrix3, Matrix4, Vector3, Vector6};

use crate::expr::{BinaryOp, Expr, LieOp, Norm, Op, UnaryOp};
use crate::tape::{Arg, CONTIGUOUS, IDENTITY, Instr, Reduce, Tape, VmapBody};
use crate::{Shape, SymbolicError};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum ArgKey {
    C(u64),
    S(u32),
}

impl From<Arg> for ArgKey {
    fn from(a: Arg) -> Self {
        match a {
            // +0.0 and -0.0 fold to the same key.
            Arg::Const(c) => ArgKey::C(if c == 0.0 { 0 } else { c.to_bits() }),
            Arg::Slot(s) => ArgKey::S(s),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Eq, Hash)]
enum Key {
    Param(u32),
    Unary(UnaryOp, u32),
    Binary(BinaryOp, ArgKey, ArgKey),
    Reduce(Reduce, Vec<ArgKey>),
    Lie(LieOp, Vec<ArgKey>),
    External(usize, Vec<ArgKey>),
}

/// A registered parameter of the function being compiled.
#[derive(Debug, Clone)]
pub(crate) struct ParamInfo {
    pub(crate) name: Arc<str>,
    pub(crate) shape: Shape,
    pub(crate) offset: usize,
}

/// What a leaf variable maps to.
#[derive(Debug, Clone)]
pub(crate) struct InputInfo {
    pub(crate) offset: usize,
    pub(crate) shape: Shape,
}

pub(crate) struct Builder<'a> {
    pub(crate) tape: Tape,
    deps: Vec<Vec<u32>>,
    cse: HashMap<Key, u32>,
    /// `slot = coeff · base` records, for detecting `constant_screw · angle`.
    lin: Vec<Option<(f64, u32)>>,
    inputs: &'a HashMap<Arc<str>, InputInfo>,
    input_slots: HashMap<u32, u32>,
    pub(crate) params: Vec<ParamInfo>,
    pub(crate) param_values: Vec<f64>,
    param_lookup: HashMap<Arc<str>, usize>,
    memo: HashMap<usize, Vec<Arg>>,
    const_slots: HashMap<u64, u32>,
    /// Body mode: the placeholder id and width (its row is the parameter block).
    placeholder: Option<(u64, usize)>,
    /// Body mode: captured outer arguments, and outer slot → body input index.
    pub(crate) captured: Vec<Arg>,
    captured_index: HashMap<u32, u32>,
    placeholder_memo: HashMap<usize, bool>,
}

type Res<T> = Result<T, SymbolicError>;

fn next_tape_id() -> u64 {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
    NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
}

impl<'a> Builder<'a> {
    pub(crate) fn new(inputs: &'a HashMap<Arc<str>, InputInfo>, n_inputs: usize) -> Self {
        Builder {
            tape: Tape { n_inputs, id: next_tape_id(), ..Tape::default() },
            deps: Vec::new(),
            cse: HashMap::new(),
            lin: Vec::new(),
            inputs,
            input_slots: HashMap::new(),
            params: Vec::new(),
            param_values: Vec::new(),
            param_lookup: HashMap::new(),
            memo: HashMap::new(),
            const_slots: HashMap::new(),
            placeholder: None,
            captured: Vec::new(),
            captured_index: HashMap::new(),
            placeholder_memo: HashMap::new(),
        }
    }

    /// Finalises dependency offsets.
    pub(crate) fn finish(mut self) -> (Tape, Vec<ParamInfo>, Vec<f64>) {
        let mut off = Vec::with_capacity(self.deps.len() + 1);
        let mut cols = Vec::new();
        off.push(0u32);
        for d in &self.deps {
            cols.extend_from_slice(d);
            off.push(cols.len() as u32);
        }
        self.tape.dep_off = off;
        self.tape.dep_cols = cols;
        (self.tape, self.params, self.param_values)
    }

    pub(crate) fn slot_deps(&self, s: u32) -> &[u32] {
        &self.deps[s as usize]
    }

    fn new_slot(&mut self, deps: Vec<u32>) -> u32 {
        self.deps.push(deps);
        self.lin.push(None);
        (self.deps.len() - 1) as u32
    }

    fn arg_deps(&self, a: Arg) -> &[u32] {
        match a {
            Arg::Const(_) => &[],
            Arg::Slot(s) => &self.deps[s as usize],
        }
    }

    /// Sorted union of the operands' dependency columns.
    fn union(&self, args: &[Arg]) -> Vec<u32> {
        let mut u: Vec<u32> = args.iter().flat_map(|&a| self.arg_deps(a).iter().copied()).collect();
        u.sort_unstable();
        u.dedup();
        u
    }

    /// Scatter map of an operand's columns into `out` columns: IDENTITY if equal (or empty),
    /// CONTIGUOUS|offset if they form a run, else a gather map.
    fn map(&mut self, operand: &[u32], out: &[u32]) -> u32 {
        if operand == out || operand.is_empty() {
            return IDENTITY;
        }
        let pos: Vec<u32> = operand
            .iter()
            .map(|c| {
                out.binary_search(c).expect("operand columns are a subset of the union") as u32
            })
            .collect();
        if pos.windows(2).all(|w| w[1] == w[0] + 1) {
            return CONTIGUOUS | pos[0];
        }
        let start = self.tape.maps.len() as u32;
        self.tape.maps.extend(pos);
        start
    }

    /// The slot of an operand; constants get a slot preset in every workspace.
    fn slot(&mut self, a: Arg) -> u32 {
        match a {
            Arg::Slot(s) => s,
            Arg::Const(c) => {
                let bits = if c == 0.0 { 0 } else { c.to_bits() };
                if let Some(&s) = self.const_slots.get(&bits) {
                    return s;
                }
                let s = self.new_slot(Vec::new());
                self.tape.consts.push((s, c));
                self.const_slots.insert(bits, s);
                s
            }
        }
    }

    // ----- scalar emission with folding ------------------------------------------------------

    fn input(&mut self, index: u32) -> Arg {
        if let Some(&s) = self.input_slots.get(&index) {
            return Arg::Slot(s);
        }
        let s = self.new_slot(vec![index]);
        self.tape.instrs.push(Instr::Input { out: s, index });
        self.input_slots.insert(index, s);
        Arg::Slot(s)
    }

    fn param(&mut self, index: u32) -> Arg {
        if let Some(&s) = self.cse.get(&Key::Param(index)) {
            return Arg::Slot(s);
        }
        let s = self.new_slot(Vec::new());
        self.tape.instrs.push(Instr::Param { out: s, index });
        self.cse.insert(Key::Param(index), s);
        Arg::Slot(s)
    }

    pub(crate) fn unary(&mut self, op: UnaryOp, x: Arg) -> Arg {
        let xs = match x {
            Arg::Const(c) => return Arg::Const(op.eval(c).0),
            Arg::Slot(s) => s,
        };
        let key = Key::Unary(op, xs);
        if let Some(&s) = self.cse.get(&key) {
            return Arg::Slot(s);
        }
        let deps = self.deps[xs as usize].clone();
        let s = self.new_slot(deps);
        if op == UnaryOp::Neg {
            let (c, b) = self.lin[xs as usize].unwrap_or((1.0, xs));
            self.lin[s as usize] = Some((-c, b));
        }
        self.tape.instrs.push(Instr::Unary { op, x: xs, out: s });
        self.cse.insert(key, s);
        Arg::Slot(s)
    }

    pub(crate) fn binary(&mut self, op: BinaryOp, x: Arg, y: Arg) -> Arg {
        use Arg::{Const, Slot};
        use BinaryOp::*;
        match (op, x, y) {
            (_, Const(a), Const(b)) => return Const(op.eval(a, b).0),
            (Add, a, Const(z)) | (Add, Const(z), a) | (Sub, a, Const(z)) if z == 0.0 => return a,
            (Sub, Const(0.0), a) => return self.unary(UnaryOp::Neg, a),
            (Mul, _, Const(z)) | (Mul, Const(z), _) if z == 0.0 => return Const(0.0),
            (Mul, a, Const(o)) | (Mul, Const(o), a) | (Div, a, Const(o)) if o == 1.0 => return a,
            (Mul, a, Const(m)) | (Mul, Const(m), a) if m == -1.0 => {
                return self.unary(UnaryOp::Neg, a);
            }
            (Div, Const(0.0), _) => return Const(0.0),
            (Div, a, Const(c)) => return self.binary(Mul, a, Const(1.0 / c)),
            _ => {}
        }
        // Commutative operations take a canonical operand order for CSE.
        let (x, y) = match (op, x, y) {
            (Add | Mul, Slot(a), Const(c)) => (Const(c), Slot(a)),
            (Add | Mul, Slot(a), Slot(b)) if a > b => (Slot(b), Slot(a)),
            _ => (x, y),
        };
        let key = Key::Binary(op, x.into(), y.into());
        if let Some(&s) = self.cse.get(&key) {
            return Slot(s);
        }
        let deps = self.union(&[x, y]);
        let (xs, ys) = (self.slot(x), self.slot(y));
        let dx = self.deps[xs as usize].clone();
        let mx = self.map(&dx, &deps);
        let dy = self.deps[ys as usize].clone();
        let my = self.map(&dy, &deps);
        let s = self.new_slot(deps);
        if let (Mul, Const(c), Slot(b)) = (op, x, y) {
            let (c0, base) = self.lin[b as usize].unwrap_or((1.0, b));
            self.lin[s as usize] = Some((c * c0, base));
        }
        let (x, y, out) = (xs, ys, s);
        self.tape.instrs.push(match op {
            Add => Instr::Add { x, y, out, mx, my },
            Sub => Instr::Sub { x, y, out, mx, my },
            Mul => Instr::Mul { x, y, out, mx, my },
            _ => Instr::Binary { op, x, y, out, mx, my },
        });
        self.cse.insert(key, s);
        Slot(s)
    }

    fn add(&mut self, x: Arg, y: Arg) -> Arg {
        self.binary(BinaryOp::Add, x, y)
    }
    fn sub(&mut self, x: Arg, y: Arg) -> Arg {
        self.binary(BinaryOp::Sub, x, y)
    }
    fn mul(&mut self, x: Arg, y: Arg) -> Arg {
        self.binary(BinaryOp::Mul, x, y)
    }

    fn sum(&mut self, xs: impl IntoIterator<Item = Arg>) -> Arg {
        xs.into_iter().fold(Arg::Const(0.0), |acc, x| self.add(acc, x))
    }

    /// `c0 + Σ cᵢ·xᵢ`, skipping zero coefficients.
    fn lincomb(&mut self, c0: f64, terms: &[(f64, Arg)]) -> Arg {
        let mut acc = Arg::Const(c0);
        for &(c, x) in terms {
            if c != 0.0 {
                let t = self.mul(Arg::Const(c), x);
                acc = self.add(acc, t);
            }
        }
        acc
    }

    /// Registers operand maps for a multi-operand instruction; returns (a0, maps, union).
    fn multi(&mut self, args: &[Arg]) -> (u32, u32, Vec<u32>) {
        let deps = self.union(args);
        let slots: Vec<u32> = args.iter().map(|&a| self.slot(a)).collect();
        let a0 = self.tape.args.len() as u32;
        self.tape.args.extend_from_slice(&slots);
        let maps = self.tape.maps.len() as u32;
        for &s in &slots {
            for c in &self.deps[s as usize] {
                let p = deps.binary_search(c).expect("subset");
                self.tape.maps.push(p as u32);
            }
        }
        (a0, maps, deps)
    }

    /// `(sin x, cos x)` with one fused instruction (shared with later `sin`/`cos` of `x`).
    fn sin_cos(&mut self, x: Arg) -> (Arg, Arg) {
        let xs = match x {
            Arg::Const(c) => return (Arg::Const(c.sin()), Arg::Const(c.cos())),
            Arg::Slot(s) => s,
        };
        if let (Some(&s), Some(&c)) = (
            self.cse.get(&Key::Unary(UnaryOp::Sin, xs)),
            self.cse.get(&Key::Unary(UnaryOp::Cos, xs)),
        ) {
            return (Arg::Slot(s), Arg::Slot(c));
        }
        let deps = self.deps[xs as usize].clone();
        let s = self.new_slot(deps.clone());
        self.new_slot(deps);
        self.tape.instrs.push(Instr::SinCos { x: xs, out: s });
        self.cse.insert(Key::Unary(UnaryOp::Sin, xs), s);
        self.cse.insert(Key::Unary(UnaryOp::Cos, xs), s + 1);
        (Arg::Slot(s), Arg::Slot(s + 1))
    }

    fn reduce(&mut self, op: Reduce, args: &[Arg]) -> Arg {
        if args.iter().all(|a| matches!(a, Arg::Const(_))) {
            let v: Vec<f64> =
                args.iter().map(|a| if let Arg::Const(c) = a { *c } else { 0.0 }).collect();
            return Arg::Const(match op {
                Reduce::Norm2 => v.iter().map(|x| x * x).sum::<f64>().sqrt(),
                Reduce::MaxAbs => v.iter().fold(0.0, |m, x| m.max(x.abs())),
            });
        }
        let key = Key::Reduce(op, args.iter().map(|&a| a.into()).collect());
        if let Some(&s) = self.cse.get(&key) {
            return Arg::Slot(s);
        }
        let (a0, maps, deps) = self.multi(args);
        let s = self.new_slot(deps);
        self.tape.instrs.push(Instr::Reduce { op, a0, n: args.len() as u32, out: s, maps });
        self.cse.insert(key, s);
        Arg::Slot(s)
    }

    /// Emits a multi-output instruction (CSE'd on `key`): operand maps, `nout` output slots
    /// with the operands' joint columns, and the instruction made by `instr(a0, n, out, nout,
    /// maps)`.
    fn emit_multi(
        &mut self,
        key: Key,
        args: &[Arg],
        nout: usize,
        instr: impl FnOnce(u32, u32, u32, u32, u32) -> Instr,
    ) -> Vec<Arg> {
        if let Some(&s) = self.cse.get(&key) {
            return (0..nout as u32).map(|k| Arg::Slot(s + k)).collect();
        }
        let (a0, maps, deps) = self.multi(args);
        let first = self.new_slot(deps.clone());
        for _ in 1..nout {
            self.new_slot(deps.clone());
        }
        self.tape.instrs.push(instr(a0, args.len() as u32, first, nout as u32, maps));
        self.cse.insert(key, first);
        (0..nout as u32).map(|k| Arg::Slot(first + k)).collect()
    }

    fn lie_instr(&mut self, op: LieOp, args: &[Arg], nout: usize) -> Vec<Arg> {
        let key = Key::Lie(op, args.iter().map(|&a| a.into()).collect());
        self.emit_multi(key, args, nout, |a0, n, out, nout, maps| Instr::Lie {
            op,
            a0,
            n,
            out,
            nout,
            maps,
        })
    }

    // ----- expression lowering ---------------------------------------------------------------

    /// Lowers an expression to its row-major entries. `outer` is the enclosing builder when
    /// this one compiles a vmap body.
    pub(crate) fn lower(&mut self, e: &Expr, mut outer: Option<&mut Builder<'_>>) -> Res<Vec<Arg>> {
        if let Some(v) = self.memo.get(&e.ptr()) {
            return Ok(v.clone());
        }
        if let Some((id, _)) = self.placeholder
            && !self.depends_on_placeholder(e, id)
        {
            let out =
                outer.as_deref_mut().expect("body mode has an outer builder").lower(e, None)?;
            let v = out.into_iter().map(|a| self.capture(a)).collect::<Vec<_>>();
            self.memo.insert(e.ptr(), v.clone());
            return Ok(v);
        }
        let n = &e.0;
        let shape = n.shape;
        let v: Vec<Arg> = match &n.op {
            Op::Invalid(err) => return Err(err.clone()),
            Op::Variable(name) => {
                let info = self
                    .inputs
                    .get(name)
                    .ok_or_else(|| SymbolicError::UnknownVariable { name: name.to_string() })?;
                if info.shape != shape {
                    return Err(SymbolicError::DuplicateName {
                        name: name.to_string(),
                        detail: format!(
                            "input group has it as {}, the expression as {shape}",
                            info.shape
                        ),
                    });
                }
                let base = info.offset as u32;
                (0..shape.numel() as u32).map(|k| self.input(base + k)).collect()
            }
            Op::Parameter(name, value) => {
                let base = self.register_param(name, shape, value)?;
                (0..shape.numel() as u32).map(|k| self.param(base as u32 + k)).collect()
            }
            Op::Constant(d) => d.iter().map(|&c| Arg::Const(c)).collect(),
            Op::Placeholder(id) => match self.placeholder {
                Some((pid, cols)) if pid == *id => {
                    (0..cols as u32).map(|k| self.param(k)).collect()
                }
                _ => {
                    return Err(SymbolicError::BadData {
                        what: "constant",
                        name: "vmap row".into(),
                        reason: "used outside its vmap body".into(),
                    });
                }
            },
            Op::Unary(op) => {
                let a = self.lower(&n.args[0], outer)?;
                a.into_iter().map(|x| self.unary(*op, x)).collect()
            }
            Op::Binary(op) => {
                let a = self.lower(&n.args[0], outer.as_deref_mut())?;
                let b = self.lower(&n.args[1], outer)?;
                let len = shape.numel();
                (0..len)
                    .map(|k| {
                        let x = if a.len() == 1 { a[0] } else { a[k] };
                        let y = if b.len() == 1 { b[0] } else { b[k] };
                        self.binary(*op, x, y)
                    })
                    .collect()
            }
            Op::MatMul => {
                let (sa, sb) = (n.args[0].0.shape, n.args[1].0.shape);
                let a = self.lower(&n.args[0], outer.as_deref_mut())?;
                let b = self.lower(&n.args[1], outer)?;
                // A vector on the left is a row, on the right a column.
                let (r, k) =
                    if let Shape::Vector(len) = sa { (1, len) } else { (sa.rows(), sa.cols()) };
                let c = if let Shape::Vector(_) = sb { 1 } else { sb.cols() };
                let mut out = Vec::with_capacity(r * c);
                for i in 0..r {
                    for j in 0..c {
                        let mut acc = Arg::Const(0.0);
                        for l in 0..k {
                            let t = self.mul(a[i * k + l], b[l * c + j]);
                            acc = self.add(acc, t);
                        }
                        out.push(acc);
                    }
                }
                out
            }
            Op::Gather(idx) => {
                let a = self.lower(&n.args[0], outer)?;
                idx.iter().map(|&i| a[i]).collect()
            }
            Op::Concat => {
                let mut out = Vec::with_capacity(shape.numel());
                for x in &n.args {
                    out.extend(self.lower(x, outer.as_deref_mut())?);
                }
                out
            }
            Op::Sum => {
                let a = self.lower(&n.args[0], outer)?;
                vec![self.sum(a)]
            }
            Op::Norm(kind) => {
                let a = self.lower(&n.args[0], outer)?;
                vec![match kind {
                    Norm::L1 => {
                        let abs: Vec<Arg> =
                            a.into_iter().map(|x| self.unary(UnaryOp::Abs, x)).collect();
                        self.sum(abs)
                    }
                    Norm::L2 if a.len() == 1 => self.unary(UnaryOp::Abs, a[0]),
                    Norm::L2 => self.reduce(Reduce::Norm2, &a),
                    Norm::Inf if a.len() == 1 => self.unary(UnaryOp::Abs, a[0]),
                    Norm::Inf => self.reduce(Reduce::MaxAbs, &a),
                }]
            }
            Op::Cross => {
                let a = self.lower(&n.args[0], outer.as_deref_mut())?;
                let b = self.lower(&n.args[1], outer)?;
                (0..3)
                    .map(|i| {
                        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
                        let p = self.mul(a[j], b[k]);
                        let q = self.mul(a[k], b[j]);
                        self.sub(p, q)
                    })
                    .collect()
            }
            Op::QuatToMatrix => {
                let q = self.lower(&n.args[0], outer)?;
                self.quat_to_matrix(&q)
            }
            Op::Lie(op) => {
                let a = self.lower(&n.args[0], outer)?;
                self.lower_lie(*op, &a)
            }
            Op::External(func) => {
                let mut a = Vec::new();
                for x in &n.args {
                    a.extend(self.lower(x, outer.as_deref_mut())?);
                }
                self.external(func, &a)
            }
            Op::Vmap { body, placeholder, batch, cols } => {
                if self.placeholder.is_some() {
                    return Err(SymbolicError::BadData {
                        what: "constant",
                        name: "vmap".into(),
                        reason: "a vmap inside a vmap body is not supported".into(),
                    });
                }
                self.lower_vmap(body, *placeholder, batch.clone(), *cols)?
            }
        };
        debug_assert_eq!(v.len(), shape.numel());
        self.memo.insert(e.ptr(), v.clone());
        Ok(v)
    }

    fn register_param(&mut self, name: &Arc<str>, shape: Shape, value: &[f64]) -> Res<usize> {
        if let Some(&i) = self.param_lookup.get(name) {
            let p = &self.params[i];
            if p.shape != shape || self.param_values[p.offset..p.offset + shape.numel()] != *value {
                return Err(SymbolicError::DuplicateName {
                    name: name.to_string(),
                    detail: "two parameter leaves with different shapes or initial values".into(),
                });
            }
            return Ok(p.offset);
        }
        if self.inputs.contains_key(name) {
            return Err(SymbolicError::DuplicateName {
                name: name.to_string(),
                detail: "it is both a variable and a parameter".into(),
            });
        }
        // In body mode the row occupies parameters 0..cols; real parameters are captured.
        let offset = self.param_values.len();
        self.param_values.extend_from_slice(value);
        self.param_lookup.insert(name.clone(), self.params.len());
        self.params.push(ParamInfo { name: name.clone(), shape, offset });
        Ok(offset)
    }

    fn quat_to_matrix(&mut self, q: &[Arg]) -> Vec<Arg> {
        let sq: Vec<Arg> = q.iter().map(|&x| self.unary(UnaryOp::Square, x)).collect();
        let n2 = self.sum(sq.iter().copied());
        let inv = self.binary(BinaryOp::Div, Arg::Const(1.0), n2);
        let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
        let mut p = |a: Arg, b: Arg| self.mul(a, b);
        let (xy, wz, xz, wy, yz, wx) = (p(x, y), p(w, z), p(x, z), p(w, y), p(y, z), p(w, x));
        let (ww, xx, yy, zz) = (sq[0], sq[1], sq[2], sq[3]);
        // Entries of (n²·R): diagonal w²+a²−b²−c², off-diagonal 2(ab ∓ wc).
        let d0 = self.lincomb(0.0, &[(1.0, ww), (1.0, xx), (-1.0, yy), (-1.0, zz)]);
        let d1 = self.lincomb(0.0, &[(1.0, ww), (-1.0, xx), (1.0, yy), (-1.0, zz)]);
        let d2 = self.lincomb(0.0, &[(1.0, ww), (-1.0, xx), (-1.0, yy), (1.0, zz)]);
        let raw = [
            d0,
            self.lincomb(0.0, &[(2.0, xy), (-2.0, wz)]),
            self.lincomb(0.0, &[(2.0, xz), (2.0, wy)]),
            self.lincomb(0.0, &[(2.0, xy), (2.0, wz)]),
            d1,
            self.lincomb(0.0, &[(2.0, yz), (-2.0, wx)]),
            self.lincomb(0.0, &[(2.0, xz), (-2.0, wy)]),
            self.lincomb(0.0, &[(2.0, yz), (2.0, wx)]),
            d2,
        ];
        raw.into_iter().map(|r| self.mul(r, inv)).collect()
    }

    /// `args = coeffs · θ` for one slot θ (entries constant zero allowed)?
    fn screw_form(&self, args: &[Arg]) -> Option<(Vec<f64>, u32)> {
        let mut base = None;
        let mut coeffs = Vec::with_capacity(args.len());
        for &a in args {
            match a {
                Arg::Const(0.0) => coeffs.push(0.0),
                Arg::Const(_) => return None,
                Arg::Slot(s) => {
                    let (c, b) = self.lin[s as usize].unwrap_or((1.0, s));
                    if *base.get_or_insert(b) != b {
                        return None;
                    }
                    coeffs.push(c);
                }
            }
        }
        base.map(|b| (coeffs, b))
    }

    /// Rotation entries `R(φ) = (I + U²) + sin φ·U − cos φ·U²` of a unit axis `u`, and the
    /// Arg triple (φ, sin φ, cos φ).
    fn axis_rotation(&mut self, u: &Vector3<f64>, phi: Arg) -> (Vec<Arg>, Arg, Arg) {
        let w = SO3::hat(u);
        let w2 = u * u.transpose() - Matrix3::identity();
        let (s, c) = self.sin_cos(phi);
        let r = (0..9)
            .map(|e| {
                let (i, j) = (e / 3, e % 3);
                let id = if i == j { 1.0 } else { 0.0 };
                self.lincomb(id + w2[(i, j)], &[(w[(i, j)], s), (-w2[(i, j)], c)])
            })
            .collect();
        (r, s, c)
    }

    fn lower_lie(&mut self, op: LieOp, a: &[Arg]) -> Vec<Arg> {
        // Constant operands fold at compile time.
        if a.iter().all(|x| matches!(x, Arg::Const(_))) {
            let c: Vec<f64> =
                a.iter().map(|x| if let Arg::Const(v) = x { *v } else { 0.0 }).collect();
            let v: Vec<f64> = match op {
                LieOp::So3Exp => {
                    let m = SO3::exp(&Vector3::new(c[0], c[1], c[2])).matrix();
                    (0..9).map(|e| m[(e / 3, e % 3)]).collect()
                }
                LieOp::Se3Exp => {
                    let m = SE3::exp(&Vector6::from_column_slice(&c)).matrix();
                    (0..16).map(|e| m[(e / 4, e % 4)]).collect()
                }
                LieOp::So3Log => SO3::from_matrix_unchecked(&Matrix3::from_row_slice(&c))
                    .log()
                    .iter()
                    .copied()
                    .collect(),
                LieOp::Se3Log => {
                    let m = Matrix4::from_row_slice(&c);
                    let r = SO3::from_matrix_unchecked(&m.fixed_view::<3, 3>(0, 0).into_owned());
                    SE3::from_parts(r, Vector3::new(c[3], c[7], c[11]))
                        .log()
                        .iter()
                        .copied()
                        .collect()
                }
            };
            return v.into_iter().map(Arg::Const).collect();
        }
        match op {
            LieOp::So3Exp => {
                if let Some((k, theta)) = self.screw_form(a) {
                    let axis = Vector3::new(k[0], k[1], k[2]);
                    let scale = axis.norm();
                    let phi = self.mul(Arg::Const(scale), Arg::Slot(theta));
                    return self.axis_rotation(&(axis / scale), phi).0;
                }
                self.lie_instr(op, a, 9)
            }
            LieOp::Se3Exp => {
                let mut out = if let Some((k, theta)) = self.screw_form(a) {
                    self.screw_exp(&k, theta)
                } else {
                    self.lie_instr(op, a, 12)
                };
                out.extend([0.0, 0.0, 0.0, 1.0].map(Arg::Const));
                out
            }
            LieOp::So3Log => self.lie_instr(op, a, 3),
            LieOp::Se3Log => self.lie_instr(op, &a[..12], 6),
        }
    }

    /// The top 12 entries of `exp(s·θ)` for a constant screw `s = [v; ω]`, as scalar
    /// combinations of θ, sin(|ω|θ) and cos(|ω|θ) with zero coefficients folded away.
    fn screw_exp(&mut self, s: &[f64], theta: u32) -> Vec<Arg> {
        let v = Vector3::new(s[0], s[1], s[2]);
        let w = Vector3::new(s[3], s[4], s[5]);
        let a = w.norm();
        let mut out = Vec::with_capacity(12);
        if a == 0.0 {
            // Prismatic: pure translation θ·v.
            let t: Vec<Arg> =
                (0..3).map(|i| self.mul(Arg::Const(v[i]), Arg::Slot(theta))).collect();
            for i in 0..3 {
                for j in 0..3 {
                    out.push(Arg::Const(if i == j { 1.0 } else { 0.0 }));
                }
                out.push(t[i]);
            }
            return out;
        }
        // Unit axis u, v' = v/a, angle φ = aθ:
        // t(φ) = U v' + sin φ·(−U² v') + cos φ·(−U v') + φ·(v' + U² v').
        let (u, vp) = (w / a, v / a);
        let phi = self.mul(Arg::Const(a), Arg::Slot(theta));
        let (r, sn, cs) = self.axis_rotation(&u, phi);
        let uh = SO3::hat(&u);
        let u2 = u * u.transpose() - Matrix3::identity();
        let (uv, u2v) = (uh * vp, u2 * vp);
        for i in 0..3 {
            out.extend_from_slice(&r[i * 3..i * 3 + 3]);
            out.push(self.lincomb(uv[i], &[(-u2v[i], sn), (-uv[i], cs), (vp[i] + u2v[i], phi)]));
        }
        out
    }

    fn external(
        &mut self,
        func: &std::sync::Arc<dyn crate::expr::ExternalFunction>,
        args: &[Arg],
    ) -> Vec<Arg> {
        let m = func.n_outputs();
        // Constant operands fold at compile time.
        if args.iter().all(|a| matches!(a, Arg::Const(_))) {
            let x: Vec<f64> =
                args.iter().map(|a| if let Arg::Const(c) = a { *c } else { 0.0 }).collect();
            let mut v = vec![0.0; m];
            let mut j = vec![0.0; m * x.len()];
            func.eval(&x, &mut v, &mut j);
            return v.into_iter().map(Arg::Const).collect();
        }
        let id = std::sync::Arc::as_ptr(func) as *const () as usize;
        let key = Key::External(id, args.iter().map(|&a| a.into()).collect());
        if let Some(&s) = self.cse.get(&key) {
            return (0..m as u32).map(|k| Arg::Slot(s + k)).collect();
        }
        let func_index =
            match self.tape.externals.iter().position(|f| std::sync::Arc::ptr_eq(f, func)) {
                Some(i) => i,
                None => {
                    self.tape.externals.push(func.clone());
                    self.tape.externals.len() - 1
                }
            } as u32;
        self.emit_multi(key, args, m, |a0, n, out, nout, maps| Instr::External {
            func: func_index,
            a0,
            n,
            out,
            nout,
            maps,
        })
    }

    // ----- vmap -----------------------------------------------------------------------------

    fn depends_on_placeholder(&mut self, e: &Expr, id: u64) -> bool {
        if let Some(&b) = self.placeholder_memo.get(&e.ptr()) {
            return b;
        }
        let b = match &e.0.op {
            Op::Placeholder(p) => *p == id,
            Op::Vmap { body, .. } => self.depends_on_placeholder(body, id),
            _ => e.0.args.iter().any(|a| self.depends_on_placeholder(a, id)),
        };
        self.placeholder_memo.insert(e.ptr(), b);
        b
    }

    /// Maps an outer argument to a body argument (constants stay constants).
    fn capture(&mut self, a: Arg) -> Arg {
        match a {
            Arg::Const(_) => a,
            Arg::Slot(s) => {
                let idx = match self.captured_index.get(&s) {
                    Some(&i) => i,
                    None => {
                        let i = self.captured.len() as u32;
                        self.captured.push(a);
                        self.captured_index.insert(s, i);
                        i
                    }
                };
                self.input(idx)
            }
        }
    }

    fn lower_vmap(
        &mut self,
        body: &Expr,
        id: u64,
        batch: Arc<[f64]>,
        cols: usize,
    ) -> Res<Vec<Arg>> {
        let rows = batch.len() / cols;
        let empty = HashMap::new();
        let mut inner = Builder::new(&empty, 0);
        inner.placeholder = Some((id, cols));
        // Reserve parameters 0..cols for the row.
        inner.param_values = vec![0.0; cols];
        let out = inner.lower(body, Some(self))?;
        let captured = std::mem::take(&mut inner.captured);
        let n_captured = captured.len();
        let (mut tape, _, _) = inner.finish();
        tape.n_inputs = n_captured;
        let output = out[0];
        if let Arg::Const(c) = output {
            return Ok(vec![Arg::Const(c); rows]);
        }
        let (a0, maps, deps) = self.multi(&captured);
        let first = self.new_slot(deps.clone());
        for _ in 1..rows {
            self.new_slot(deps.clone());
        }
        let index = self.tape.vmaps.len() as u32;
        self.tape.vmaps.push(VmapBody { tape, output, batch, cols });
        self.tape.instrs.push(Instr::Vmap {
            body: index,
            a0,
            n: n_captured as u32,
            out: first,
            nout: rows as u32,
            maps,
        });
        Ok((0..rows as u32).map(|k| Arg::Slot(first + k)).collect())
    }
}
