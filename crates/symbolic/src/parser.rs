//! A parser for expression strings, resolving names against a symbol table.
//!
//! Grammar (lowest to highest precedence):
//!
//! ```text
//! comparison := sum [("<=" | ">=" | "==") sum]
//! sum        := product (("+" | "-") product)*
//! product    := unary (("*" | "/" | "@") unary)*
//! unary      := "-" unary | power
//! power      := postfix ["**" unary]          (right-associative; -x**2 = -(x**2))
//! postfix    := primary ("[" index "]" | ".T")*
//! index      := slice ["," slice]             slice := int | [int] ":" [int]   (negatives wrap)
//! primary    := number | "pi" | name | name "(" args ")" | "(" comparison ")" | "[" args "]"
//! ```
//!
//! Functions: `sqrt square abs sin cos tan exp log tanh pos sqpos sum transpose` (one
//! argument), `norm(x[, 1|2|inf])`, `max(x, y)`, `min(x, y)`, `dot(a, b)`, `cross(a, b)`,
//! `concat(…)`, `stack(…)`, `quat_to_matrix(q)`, `so3_exp`, `so3_log`, `se3_exp`, `se3_log`,
//! `identity(n)`. Powers: integer exponents and `0.5`.

use std::collections::HashMap;

use crate::{Constraint, Expr, Norm, Shape, SymbolicError};

/// Names an expression string may use, mapped to expressions (variables, parameters,
/// constants or whole sub-expressions such as `p_ee`).
#[derive(Debug, Clone, Default)]
pub struct SymbolTable {
    map: HashMap<String, Expr>,
}

impl SymbolTable {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds (or replaces) a name.
    pub fn insert(&mut self, name: impl Into<String>, e: Expr) -> &mut Self {
        self.map.insert(name.into(), e);
        self
    }

    /// Adds a variable or parameter under its own name.
    pub fn insert_leaf(&mut self, e: &Expr) -> &mut Self {
        if let Some(n) = e.leaf_name() {
            self.map.insert(n.to_string(), e.clone());
        }
        self
    }

    /// Looks a name up.
    pub fn get(&self, name: &str) -> Option<&Expr> {
        self.map.get(name)
    }

    fn closest(&self, name: &str) -> Option<&str> {
        self.map
            .keys()
            .map(|k| (edit_distance(k, name), k))
            .filter(|(d, _)| *d <= 2)
            .min()
            .map(|(_, k)| k.as_str())
    }
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, cb) in b.iter().enumerate() {
            cur.push((prev[j] + usize::from(ca != *cb)).min(prev[j + 1] + 1).min(cur[j] + 1));
        }
        prev = cur;
    }
    prev[b.len()]
}

/// Parses an expression.
///
/// # Errors
/// [`SymbolicError::Parse`] with the column of the offending character and a caret line,
/// for syntax errors, unknown names and shape errors alike.
///
/// ```
/// use armature_symbolic::{parse_expr, Expr, Shape, SymbolTable};
/// let mut s = SymbolTable::new();
/// s.insert_leaf(&Expr::variable("x", 3));
/// let e = parse_expr("norm(x - [1, 2, 3], 2) * 2", &s).unwrap();
/// assert_eq!(e.shape().unwrap(), Shape::Scalar);
/// let err = parse_expr("norm(x - y)", &s).unwrap_err().to_string();
/// assert!(err.starts_with("unknown name 'y' (did you mean 'x'?) at column 10"), "{err}");
/// assert!(err.ends_with("^"), "{err}");
/// ```
pub fn parse_expr(text: &str, symbols: &SymbolTable) -> Result<Expr, SymbolicError> {
    let mut p = Parser::new(text, symbols)?;
    let e = p.sum()?;
    p.expect_end()?;
    Ok(e)
}

/// Parses a comparison `lhs <= rhs`, `lhs >= rhs` or `lhs == rhs` into a (nodal, all
/// nodes) [`Constraint`] named after the text.
///
/// # Errors
/// As [`parse_expr`], and a missing comparison operator.
pub fn parse_constraint(text: &str, symbols: &SymbolTable) -> Result<Constraint, SymbolicError> {
    let mut p = Parser::new(text, symbols)?;
    let lhs = p.sum()?;
    let (op, at) = match p.peek() {
        Tok::Le | Tok::Ge | Tok::EqEq => (p.peek().clone(), p.pos()),
        _ => return Err(p.error_here("expected a comparison (<=, >= or ==)")),
    };
    p.next();
    let rhs = p.sum()?;
    p.expect_end()?;
    let c = match op {
        Tok::Le => lhs.le(rhs),
        Tok::Ge => lhs.ge(rhs),
        _ => lhs.eq(rhs),
    };
    p.checked(c.function().clone(), at)?;
    Ok(c.named(text.trim()))
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Plus,
    Minus,
    Star,
    Slash,
    At,
    Pow,
    LParen,
    RParen,
    LBrack,
    RBrack,
    Comma,
    Colon,
    Dot,
    Le,
    Ge,
    EqEq,
    End,
}

struct Parser<'a> {
    text: &'a str,
    toks: Vec<(Tok, usize)>,
    i: usize,
    symbols: &'a SymbolTable,
    /// Current recursion depth (see [`MAX_NESTING`]).
    depth: usize,
}

/// Deepest nesting of parentheses, brackets, calls and unary minus an expression may have:
/// the parser and the expression graph's passes recurse, and untrusted input must not
/// overflow the stack.
pub const MAX_NESTING: usize = 64;

/// Largest `n` of `identity(n)` in an expression string.
pub const MAX_IDENTITY: usize = 1_000;

/// Most tokens an expression may have (a long chain `x + x + …` builds a tree as deep as it
/// is long).
pub const MAX_TOKENS: usize = 1_000;

fn lex(text: &str) -> Result<Vec<(Tok, usize)>, SymbolicError> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        // Bytes, not chars: only ASCII forms tokens, and the index stays on char boundaries
        // (a UTF-8 continuation byte such as 0xA0 is not whitespace here).
        let c = b[i] as char;
        if b[i].is_ascii_whitespace() {
            i += 1;
            continue;
        }
        let start = i;
        let two = text.get(i..i + 2).unwrap_or("");
        let tok = match two {
            "<=" => Some(Tok::Le),
            ">=" => Some(Tok::Ge),
            "==" => Some(Tok::EqEq),
            "**" => Some(Tok::Pow),
            _ => None,
        };
        if let Some(t) = tok {
            out.push((t, start));
            i += 2;
            continue;
        }
        let tok = match c {
            '+' => Tok::Plus,
            '-' => Tok::Minus,
            '*' => Tok::Star,
            '/' => Tok::Slash,
            '@' => Tok::At,
            '(' => Tok::LParen,
            ')' => Tok::RParen,
            '[' => Tok::LBrack,
            ']' => Tok::RBrack,
            ',' => Tok::Comma,
            ':' => Tok::Colon,
            '.' if !(i + 1 < b.len() && b[i + 1].is_ascii_digit()) => Tok::Dot,
            '<' | '>' => {
                return Err(SymbolicError::parse(
                    format!("use '{c}=': strict comparisons are not supported"),
                    text,
                    i,
                ));
            }
            '=' => return Err(SymbolicError::parse("use '==' for equality", text, i)),
            c if c.is_ascii_digit() || c == '.' => {
                let mut j = i;
                while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.') {
                    j += 1;
                }
                if j < b.len() && (b[j] == b'e' || b[j] == b'E') {
                    let mut k = j + 1;
                    if k < b.len() && (b[k] == b'+' || b[k] == b'-') {
                        k += 1;
                    }
                    if k < b.len() && b[k].is_ascii_digit() {
                        j = k;
                        while j < b.len() && b[j].is_ascii_digit() {
                            j += 1;
                        }
                    }
                }
                let v: f64 = text[i..j].parse().map_err(|_| {
                    SymbolicError::parse(format!("bad number '{}'", &text[i..j]), text, i)
                })?;
                i = j;
                out.push((Tok::Num(v), start));
                continue;
            }
            c if c.is_ascii_alphabetic() || c == '_' => {
                let mut j = i;
                while j < b.len() && (b[j].is_ascii_alphanumeric() || b[j] == b'_') {
                    j += 1;
                }
                let name = text[i..j].to_string();
                i = j;
                out.push((Tok::Name(name), start));
                continue;
            }
            _ => {
                return Err(SymbolicError::parse(
                    format!("unexpected character '{}'", text[i..].chars().next().unwrap_or('?')),
                    text,
                    i,
                ));
            }
        };
        out.push((tok, start));
        i += 1;
    }
    out.push((Tok::End, text.len()));
    Ok(out)
}

/// One side of an index: a single position or a range.
enum Sel {
    One(usize),
    Range(usize, usize),
}

impl<'a> Parser<'a> {
    fn new(text: &'a str, symbols: &'a SymbolTable) -> Result<Self, SymbolicError> {
        let toks = lex(text)?;
        if toks.len() > MAX_TOKENS + 1 {
            return Err(SymbolicError::parse(
                format!(
                    "expression of {} tokens is longer than the limit of {MAX_TOKENS}",
                    toks.len() - 1
                ),
                text,
                toks[MAX_TOKENS].1,
            ));
        }
        Ok(Parser { text, toks, i: 0, symbols, depth: 0 })
    }

    fn peek(&self) -> &Tok {
        &self.toks[self.i].0
    }

    fn pos(&self) -> usize {
        self.toks[self.i].1
    }

    fn next(&mut self) -> Tok {
        let t = self.toks[self.i].0.clone();
        if t != Tok::End {
            self.i += 1;
        }
        t
    }

    fn error_at(&self, msg: impl Into<String>, at: usize) -> SymbolicError {
        SymbolicError::parse(msg, self.text, at)
    }

    fn error_here(&self, msg: &str) -> SymbolicError {
        let found = match self.peek() {
            Tok::End => "end of input".to_string(),
            _ => format!("'{}'", self.text[self.pos()..].split_whitespace().next().unwrap_or("")),
        };
        self.error_at(format!("{msg}, found {found}"), self.pos())
    }

    fn expect(&mut self, t: Tok, what: &str) -> Result<(), SymbolicError> {
        if *self.peek() == t {
            self.next();
            Ok(())
        } else {
            Err(self.error_here(&format!("expected {what}")))
        }
    }

    fn expect_end(&self) -> Result<(), SymbolicError> {
        match self.peek() {
            Tok::End => Ok(()),
            Tok::Le | Tok::Ge | Tok::EqEq => {
                Err(self.error_here("a comparison is not allowed here"))
            }
            _ => Err(self.error_here("expected an operator or the end")),
        }
    }

    /// Turns a shape error of a freshly built expression into a positioned parse error.
    fn checked(&self, e: Expr, at: usize) -> Result<Expr, SymbolicError> {
        match e.shape() {
            Ok(_) => Ok(e),
            Err(err) => Err(self.error_at(err.to_string(), at)),
        }
    }

    fn sum(&mut self) -> Result<Expr, SymbolicError> {
        let mut lhs = self.product()?;
        loop {
            let at = self.pos();
            let e = match self.peek() {
                Tok::Plus => {
                    self.next();
                    &lhs + &self.product()?
                }
                Tok::Minus => {
                    self.next();
                    &lhs - &self.product()?
                }
                _ => return Ok(lhs),
            };
            lhs = self.checked(e, at)?;
        }
    }

    fn product(&mut self) -> Result<Expr, SymbolicError> {
        let mut lhs = self.unary()?;
        loop {
            let at = self.pos();
            let e = match self.peek() {
                Tok::Star => {
                    self.next();
                    &lhs * &self.unary()?
                }
                Tok::Slash => {
                    self.next();
                    &lhs / &self.unary()?
                }
                Tok::At => {
                    self.next();
                    lhs.matmul(&self.unary()?)
                }
                _ => return Ok(lhs),
            };
            lhs = self.checked(e, at)?;
        }
    }

    /// Every recursive path (parentheses, brackets, calls, `-`, `**`) passes through here.
    fn unary(&mut self) -> Result<Expr, SymbolicError> {
        if self.depth >= MAX_NESTING {
            return Err(
                self.error_here(&format!("expression nested deeper than {MAX_NESTING} levels"))
            );
        }
        self.depth += 1;
        let out = self.unary_inner();
        self.depth -= 1;
        out
    }

    fn unary_inner(&mut self) -> Result<Expr, SymbolicError> {
        if *self.peek() == Tok::Minus {
            self.next();
            let e = self.unary()?;
            return Ok(match e.constant_value() {
                Some(v) if v.len() == 1 => Expr::scalar(-v[0]),
                _ => -e,
            });
        }
        self.power()
    }

    fn power(&mut self) -> Result<Expr, SymbolicError> {
        let base = self.postfix()?;
        if *self.peek() != Tok::Pow {
            return Ok(base);
        }
        let at = self.pos();
        self.next();
        let exp_at = self.pos();
        let exp = self.unary()?;
        let p = match exp.constant_value() {
            Some(v) if v.len() == 1 => v[0],
            _ => return Err(self.error_at("the exponent must be a number", exp_at)),
        };
        let e = if p == 0.5 {
            base.sqrt()
        } else if p.fract() == 0.0 && (1.0..=16.0).contains(&p) {
            // x**n by repeated squaring keeps the tape short and exact.
            let n = p as u32;
            let mut acc: Option<Expr> = None;
            let mut sq = base.clone();
            let mut k = n;
            while k > 0 {
                if k & 1 == 1 {
                    acc = Some(match acc {
                        None => sq.clone(),
                        Some(a) => &a * &sq,
                    });
                }
                k >>= 1;
                if k > 0 {
                    sq = sq.square();
                }
            }
            acc.unwrap_or(base)
        } else if p == 0.0 {
            &base * 0.0 + 1.0
        } else {
            return Err(self.error_at(
                format!("unsupported exponent {p}: use integers 0..=16 or 0.5"),
                exp_at,
            ));
        };
        self.checked(e, at)
    }

    fn postfix(&mut self) -> Result<Expr, SymbolicError> {
        let mut e = self.primary()?;
        loop {
            match self.peek() {
                Tok::LBrack => {
                    let at = self.pos();
                    self.next();
                    e = self.index(e, at)?;
                }
                Tok::Dot => {
                    let at = self.pos();
                    self.next();
                    match self.next() {
                        Tok::Name(n) if n == "T" => e = self.checked(e.transpose(), at)?,
                        _ => return Err(self.error_at("expected 'T' after '.'", at + 1)),
                    }
                }
                _ => return Ok(e),
            }
        }
    }

    fn int(&mut self, len: usize) -> Result<Option<usize>, SymbolicError> {
        let at = self.pos();
        let neg = if *self.peek() == Tok::Minus {
            self.next();
            true
        } else {
            false
        };
        match self.peek().clone() {
            Tok::Num(v) if v.fract() == 0.0 && v >= 0.0 => {
                self.next();
                let v = v as usize;
                if neg {
                    if v == 0 || v > len {
                        return Err(self
                            .error_at(format!("index -{v} is out of range for length {len}"), at));
                    }
                    Ok(Some(len - v))
                } else {
                    Ok(Some(v))
                }
            }
            Tok::Colon | Tok::Comma | Tok::RBrack if !neg => Ok(None),
            _ => Err(self.error_here("expected an integer index")),
        }
    }

    fn sel(&mut self, len: usize) -> Result<Sel, SymbolicError> {
        let a = self.int(len)?;
        if *self.peek() == Tok::Colon {
            self.next();
            let b = self.int(len)?;
            Ok(Sel::Range(a.unwrap_or(0), b.unwrap_or(len)))
        } else {
            match a {
                Some(i) => Ok(Sel::One(i)),
                None => Err(self.error_here("expected an index")),
            }
        }
    }

    fn index(&mut self, e: Expr, at: usize) -> Result<Expr, SymbolicError> {
        let shape = e.shape().map_err(|err| self.error_at(err.to_string(), at))?;
        let out = match shape {
            Shape::Matrix(r, c) => {
                let rs = self.sel(r)?;
                self.expect(Tok::Comma, "',' and a column index (matrices take two indices)")?;
                let cs = self.sel(c)?;
                let (r0, r1) = match rs {
                    Sel::One(i) => (i, i + 1),
                    Sel::Range(a, b) => (a, b),
                };
                let (c0, c1) = match cs {
                    Sel::One(j) => (j, j + 1),
                    Sel::Range(a, b) => (a, b),
                };
                e.block(r0, r1, c0, c1)
            }
            _ => match self.sel(shape.numel())? {
                Sel::One(i) => e.at(i),
                Sel::Range(a, b) => e.slice(a, b),
            },
        };
        self.expect(Tok::RBrack, "']'")?;
        self.checked(out, at)
    }

    fn args(&mut self, close: Tok) -> Result<Vec<(Expr, usize)>, SymbolicError> {
        let mut v = Vec::new();
        if *self.peek() == close {
            self.next();
            return Ok(v);
        }
        loop {
            let at = self.pos();
            v.push((self.sum()?, at));
            let msg =
                if close == Tok::RParen { "expected ',' or ')'" } else { "expected ',' or ']'" };
            match self.peek() {
                Tok::Comma => {
                    self.next();
                }
                t if *t == close => {
                    self.next();
                    return Ok(v);
                }
                _ => return Err(self.error_here(msg)),
            }
        }
    }

    fn primary(&mut self) -> Result<Expr, SymbolicError> {
        let at = self.pos();
        match self.next() {
            Tok::Num(v) => Ok(Expr::scalar(v)),
            Tok::LParen => {
                let e = self.sum()?;
                self.expect(Tok::RParen, "')'")?;
                Ok(e)
            }
            Tok::LBrack => {
                let items = self.args(Tok::RBrack)?;
                if items.is_empty() {
                    return Err(self.error_at("empty array", at));
                }
                let consts: Option<Vec<f64>> = items
                    .iter()
                    .map(|(e, _)| e.constant_value().filter(|v| v.len() == 1).map(|v| v[0]))
                    .collect();
                match consts {
                    Some(v) => Ok(Expr::constant_vector(&v)),
                    None => {
                        let parts: Vec<Expr> = items.into_iter().map(|(e, _)| e).collect();
                        self.checked(Expr::concat(&parts), at)
                    }
                }
            }
            Tok::Name(n) if n == "norm" && *self.peek() == Tok::LParen => {
                self.next();
                self.norm_call(at)
            }
            Tok::Name(n) if *self.peek() == Tok::LParen => {
                self.next();
                let args = self.args(Tok::RParen)?;
                self.call(&n, args, at)
            }
            Tok::Name(n) if n == "pi" && self.symbols.get("pi").is_none() => {
                Ok(Expr::scalar(core::f64::consts::PI))
            }
            Tok::Name(n) => match self.symbols.get(&n) {
                Some(e) => Ok(e.clone()),
                None => {
                    let hint = self
                        .symbols
                        .closest(&n)
                        .map(|k| format!(" (did you mean '{k}'?)"))
                        .unwrap_or_default();
                    Err(self.error_at(format!("unknown name '{n}'{hint}"), at))
                }
            },
            Tok::End => Err(self.error_at("unexpected end of expression", at)),
            _ => Err(self.error_at("expected a number, a name, '(' or '['", at)),
        }
    }

    /// `norm(x)`, `norm(x, 1)`, `norm(x, 2)`, `norm(x, inf)`.
    fn norm_call(&mut self, at: usize) -> Result<Expr, SymbolicError> {
        let x = self.sum()?;
        let kind = match self.peek() {
            Tok::RParen => {
                self.next();
                Norm::L2
            }
            Tok::Comma => {
                self.next();
                let ord_at = self.pos();
                let kind = match self.next() {
                    Tok::Name(n) if n == "inf" => Norm::Inf,
                    Tok::Num(1.0) => Norm::L1,
                    Tok::Num(2.0) => Norm::L2,
                    _ => return Err(self.error_at("norm order must be 1, 2 or inf", ord_at)),
                };
                self.expect(Tok::RParen, "')'")?;
                kind
            }
            _ => return Err(self.error_here("expected ',' or ')'")),
        };
        self.checked(x.norm(kind), at)
    }

    fn call(
        &mut self,
        name: &str,
        args: Vec<(Expr, usize)>,
        at: usize,
    ) -> Result<Expr, SymbolicError> {
        let arity = |n: usize| -> Result<(), SymbolicError> {
            if args.len() == n {
                Ok(())
            } else {
                Err(self.error_at(
                    format!(
                        "{name}() takes {n} argument{}, got {}",
                        if n == 1 { "" } else { "s" },
                        args.len()
                    ),
                    at,
                ))
            }
        };
        let a = |k: usize| args[k].0.clone();
        let e = match name {
            "sqrt" | "square" | "abs" | "sin" | "cos" | "tan" | "exp" | "log" | "tanh" | "pos"
            | "sqpos" | "sum" | "transpose" | "quat_to_matrix" | "so3_exp" | "so3_log"
            | "se3_exp" | "se3_log" => {
                arity(1)?;
                let x = a(0);
                match name {
                    "sqrt" => x.sqrt(),
                    "square" => x.square(),
                    "abs" => x.abs(),
                    "sin" => x.sin(),
                    "cos" => x.cos(),
                    "tan" => x.tan(),
                    "exp" => x.exp(),
                    "log" => x.log(),
                    "tanh" => x.tanh(),
                    "pos" => x.pos(),
                    "sqpos" => x.squared_pos(),
                    "sum" => x.sum(),
                    "transpose" => x.transpose(),
                    "quat_to_matrix" => x.quat_to_matrix(),
                    "so3_exp" => x.so3_exp(),
                    "so3_log" => x.so3_log(),
                    "se3_exp" => x.se3_exp(),
                    _ => x.se3_log(),
                }
            }
            "max" | "min" | "dot" | "cross" => {
                arity(2)?;
                match name {
                    "max" => a(0).max(a(1)),
                    "min" => a(0).min(a(1)),
                    "dot" => a(0).dot(&a(1)),
                    _ => a(0).cross(&a(1)),
                }
            }
            "concat" | "stack" => {
                let parts: Vec<Expr> = args.iter().map(|(e, _)| e.clone()).collect();
                if name == "concat" { Expr::concat(&parts) } else { Expr::stack(&parts) }
            }
            "identity" => {
                arity(1)?;
                match a(0).constant_value() {
                    Some([v]) if v.fract() == 0.0 && (1.0..=MAX_IDENTITY as f64).contains(v) => {
                        Expr::identity(*v as usize)
                    }
                    _ => {
                        return Err(self.error_at(
                            format!("identity() takes an integer from 1 to {MAX_IDENTITY}"),
                            args[0].1,
                        ));
                    }
                }
            }
            _ => return Err(self.error_at(format!("unknown function '{name}'"), at)),
        };
        self.checked(e, at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance_basics() {
        assert_eq!(edit_distance("angle", "angel"), 2);
        assert_eq!(edit_distance("x", "x"), 0);
        assert_eq!(edit_distance("", "ab"), 2);
    }
}
