//! Problem files: what power users write — states, controls, parameters, dynamics,
//! constraints and outputs as expression strings (parsed by `armature-symbolic`), like
//! OpenSCvx's YAML loader, in TOML.
//!
//! ```toml
//! nodes = 21
//!
//! [time]
//! max = 10.0            # free final time in [min, max], minimized (or: fixed = 2.0)
//! guess = 3.0
//!
//! [[states]]
//! name = "p"
//! initial = [0.0]       # per component: a number or "free"
//! final = [1.0]         # a number, "free", "minimize" or "maximize"
//! dynamics = "v"        # d p / dt
//!
//! [[states]]
//! name = "v"
//! min = -10.0           # one value for every component, or a list
//! max = 10.0
//! initial = [0.0]
//! final = [0.0]
//! dynamics = "a"
//!
//! [[controls]]
//! name = "a"
//! min = -1.0
//! max = 1.0
//!
//! [parameters]
//! v_max = 1.5           # a number or a list; change it without recompiling
//!
//! [[constraints]]
//! expr = "v <= v_max"
//! ctcs = true           # in continuous time (default: at the nodes)
//! # between_nodes = true  # also at each segment's peak between the nodes (states only)
//!
//! [outputs]
//! speed = "abs(v)"
//! ```
//!
//! Errors in expressions point at the offending character in the file (`file:line:col`).

use std::collections::BTreeMap;

use armature_scvx::{
    Ball, BetweenNodes, Boundary, Control, CtcsOptions, IntervalConstraint, Penalty, Problem,
    ProblemConstraint, PtrSettings, State, Time,
};
use armature_symbolic::{Expr, Shape, SymbolTable, SymbolicError, parse_constraint, parse_expr};
use serde::Deserialize;
use toml::Spanned;

use crate::task::{LocatedError, Source};

/// A parsed problem file.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProblemFile {
    /// Number of nodes (≥ 2).
    #[schemars(with = "usize")]
    pub nodes: Spanned<usize>,
    /// Final time.
    pub time: ProblemTime,
    /// States, each with its dynamics.
    pub states: Vec<StateSpec>,
    /// Controls.
    #[serde(default)]
    pub controls: Vec<ControlSpec>,
    /// Parameters: name = number or list.
    #[serde(default)]
    #[schemars(with = "BTreeMap<String, Values>")]
    pub parameters: BTreeMap<String, Spanned<Values>>,
    /// Constraints.
    #[serde(default)]
    pub constraints: Vec<ConstraintSpec>,
    /// Nodal second-order-cone constraints `‖expr‖ ≤ radius`.
    #[serde(default)]
    pub balls: Vec<BallSpec>,
    /// Algebraic outputs: name = expression, evaluated along the solution.
    #[serde(default)]
    #[schemars(with = "BTreeMap<String, String>")]
    pub outputs: BTreeMap<String, Spanned<String>>,
    /// Also enforce state bounds between nodes (ReLU CTCS, ε = 1e-6). Default true.
    #[serde(default = "yes")]
    pub state_bounds_ctcs: bool,
    /// Algorithm settings ([`armature_scvx::PtrSettings`]; every key optional).
    #[serde(default)]
    pub settings: armature_scvx::PtrSettings,
}

fn yes() -> bool {
    true
}

/// A number, or a list of numbers.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Values {
    /// One number (for every component).
    One(f64),
    /// One per component.
    Many(Vec<f64>),
}

/// A boundary condition entry: a number or a word.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Condition {
    /// Fixed to this value.
    Value(f64),
    /// `"free"`, `"minimize"` or `"maximize"`.
    Word(String),
}

/// Boundary conditions: one for every component, or a list.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Conditions {
    /// One for every component.
    One(Condition),
    /// One per component.
    Many(Vec<Condition>),
}

/// Final time: `fixed = T`, or free in `[min, max]` from `guess`.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProblemTime {
    /// A fixed final time (s).
    #[serde(default)]
    #[schemars(with = "Option<f64>")]
    pub fixed: Option<Spanned<f64>>,
    /// Upper bound of a free final time (s).
    #[serde(default)]
    #[schemars(with = "Option<f64>")]
    pub max: Option<Spanned<f64>>,
    /// Lower bound (s). Default 0.
    #[serde(default)]
    pub min: Option<f64>,
    /// Initial guess (s). Default (min + max)/2.
    #[serde(default)]
    pub guess: Option<f64>,
    /// Minimize the final time. Default true.
    #[serde(default = "yes")]
    pub minimize: bool,
}

/// A state variable.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StateSpec {
    /// Name (used in expressions).
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// Number of components. Default 1.
    #[serde(default = "one")]
    pub size: usize,
    /// Lower bounds. Default none.
    #[serde(default)]
    #[schemars(with = "Option<Values>")]
    pub min: Option<Spanned<Values>>,
    /// Upper bounds. Default none.
    #[serde(default)]
    #[schemars(with = "Option<Values>")]
    pub max: Option<Spanned<Values>>,
    /// Initial conditions. Default free.
    #[serde(default)]
    #[schemars(with = "Option<Conditions>")]
    pub initial: Option<Spanned<Conditions>>,
    /// Final conditions. Default free.
    #[serde(default, rename = "final")]
    #[schemars(with = "Option<Conditions>")]
    pub terminal: Option<Spanned<Conditions>>,
    /// Right-hand side `d name / dt`, an expression of the states, controls and parameters.
    #[schemars(with = "String")]
    pub dynamics: Spanned<String>,
    /// Also bound each segment's peak of this state between the nodes (scvx's
    /// `Ocp::interval_bounds`), for bounds the motion rides. Default false.
    #[serde(default)]
    pub interval_bounds: bool,
}

fn one() -> usize {
    1
}

/// A control variable.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ControlSpec {
    /// Name.
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// Number of components. Default 1.
    #[serde(default = "one")]
    pub size: usize,
    /// Lower bounds.
    #[serde(default)]
    #[schemars(with = "Option<Values>")]
    pub min: Option<Spanned<Values>>,
    /// Upper bounds.
    #[serde(default)]
    #[schemars(with = "Option<Values>")]
    pub max: Option<Spanned<Values>>,
    /// `"foh"` (first-order hold, default) or `"zoh"`.
    #[serde(default)]
    #[schemars(with = "Option<String>")]
    pub hold: Option<Spanned<String>>,
}

/// A constraint `lhs <= rhs`, `lhs >= rhs` or `lhs == rhs`.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ConstraintSpec {
    /// The comparison.
    #[schemars(with = "String")]
    pub expr: Spanned<String>,
    /// Name for reports. Default: the expression.
    #[serde(default)]
    pub name: Option<String>,
    /// Enforce in continuous time (CTCS). Default false (at nodes).
    #[serde(default)]
    pub ctcs: bool,
    /// Nodal: these nodes (default all).
    #[serde(default)]
    #[schemars(with = "Option<Vec<usize>>")]
    pub nodes: Option<Spanned<Vec<usize>>>,
    /// A node range `[first, last]` (CTCS interval or nodal range).
    #[serde(default)]
    #[schemars(with = "Option<[usize; 2]>")]
    #[serde(deserialize_with = "crate::task::optional_spanned_array")]
    pub over: Option<Spanned<[usize; 2]>>,
    /// CTCS penalty: `"squared_relu"` (default) or `"relu"`.
    #[serde(default)]
    #[schemars(with = "Option<PenaltyName>")]
    pub penalty: Option<Penalty>,
    /// CTCS increment per segment. Default 1e-4.
    #[serde(default)]
    pub eps: Option<f64>,
    /// CTCS group label. Default 0.
    #[serde(default)]
    pub group: Option<usize>,
    /// Also hold it at each segment's peak between the nodes (of `over`, default all):
    /// an inequality of the states only. Default false.
    #[serde(default)]
    pub between_nodes: bool,
    /// With `between_nodes`: a segment's peak rows stay out of the subproblem while its
    /// peaks lie further than this below the bound (in the constraint's units; scvx's
    /// `IntervalConstraint::activation`). Default: always in.
    #[serde(default)]
    pub activation: Option<f64>,
}

/// CTCS penalty names (for the schema).
#[derive(Debug, Clone, Copy, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
#[allow(dead_code)]
enum PenaltyName {
    /// `max(0, g)²`.
    SquaredRelu,
    /// `max(0, g)`.
    Relu,
}

/// A nodal ball.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BallSpec {
    /// The vector expression.
    #[schemars(with = "String")]
    pub expr: Spanned<String>,
    /// Radius (> 0).
    #[schemars(with = "f64")]
    pub radius: Spanned<f64>,
    /// Nodes.
    #[schemars(with = "Vec<usize>")]
    pub nodes: Spanned<Vec<usize>>,
    /// Name. Default: the expression.
    #[serde(default)]
    pub name: Option<String>,
}

/// Largest size of one state or control vector.
pub const MAX_SIZE: usize = 1_000;

/// Parses a problem file.
///
/// # Errors
/// Syntax, unknown keys, wrong types, as `file:line:col: reason`.
pub fn parse(src: Source<'_>) -> Result<ProblemFile, LocatedError> {
    toml::from_str(src.text).map_err(|e| {
        let at = e.span().map_or(0, |s| s.start);
        src.error_at(at, e.message().trim_end().to_string())
    })
}

/// An expression error located at its character in the file (inside the string value).
fn expr_error(src: Source<'_>, at: &Spanned<String>, e: SymbolicError) -> LocatedError {
    match e {
        SymbolicError::Parse { message, column, source_text, .. } => {
            // The column counts characters of the parsed value; the file may write them
            // with escapes.
            let raw = &src.text[at.span()];
            let byte = crate::toml_string::raw_offset(raw, column.saturating_sub(1));
            src.error_at(at.span().start + byte, format!("{message} in \"{source_text}\""))
        }
        other => src.error(at, other.to_string()),
    }
}

fn values(
    src: Source<'_>,
    v: &Option<Spanned<Values>>,
    n: usize,
    default: f64,
    what: &str,
) -> Result<Vec<f64>, LocatedError> {
    match v {
        None => Ok(vec![default; n]),
        Some(s) => {
            let out = match s.get_ref() {
                Values::One(x) => vec![*x; n],
                Values::Many(v) => v.clone(),
            };
            if out.len() != n {
                return Err(
                    src.error(s, format!("{what}: {} values for {n} components", out.len()))
                );
            }
            if out.iter().any(|x| x.is_nan()) {
                return Err(src.error(s, format!("{what}: NaN")));
            }
            Ok(out)
        }
    }
}

fn conditions(
    src: Source<'_>,
    c: &Option<Spanned<Conditions>>,
    n: usize,
    what: &str,
) -> Result<Vec<Boundary>, LocatedError> {
    let Some(c) = c else { return Ok(vec![Boundary::Free; n]) };
    let list = match c.get_ref() {
        Conditions::One(x) => vec![x.clone(); n],
        Conditions::Many(v) => v.clone(),
    };
    if list.len() != n {
        return Err(src.error(c, format!("{what}: {} conditions for {n} components", list.len())));
    }
    list.iter()
        .map(|x| match x {
            Condition::Value(v) if v.is_finite() => Ok(Boundary::Fixed(*v)),
            Condition::Value(v) => Err(src.error(c, format!("{what}: {v} is not finite"))),
            Condition::Word(w) => match w.as_str() {
                "free" => Ok(Boundary::Free),
                "minimize" => Ok(Boundary::Minimize),
                "maximize" => Ok(Boundary::Maximize),
                _ => Err(src.error(
                    c,
                    format!("{what}: '{w}': give a number, \"free\", \"minimize\" or \"maximize\""),
                )),
            },
        })
        .collect()
}

/// Builds the [`Problem`] and its settings from a problem file.
///
/// # Errors
/// The first problem found, as `file:line:col: reason` (expression errors at their
/// character).
pub fn build(file: &ProblemFile, src: Source<'_>) -> Result<(Problem, PtrSettings), LocatedError> {
    let nodes = *file.nodes.get_ref();
    if !(2..=armature_scvx::MAX_NODES).contains(&nodes) {
        return Err(
            src.error(&file.nodes, format!("nodes must be 2 to {}", armature_scvx::MAX_NODES))
        );
    }
    let mut symbols = parameters(file, src)?;
    let (states, controls) = variables(file, &mut symbols, src)?;
    let dynamics = file
        .states
        .iter()
        .map(|s| {
            parse_expr(s.dynamics.get_ref(), &symbols).map_err(|e| expr_error(src, &s.dynamics, e))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (constraints, between_nodes) =
        constraints(file, &symbols, nodes, (&states, &controls), src)?;
    let balls = balls(file, &symbols, nodes, src)?;
    let outputs = file
        .outputs
        .iter()
        .map(|(name, e)| {
            Ok((
                name.clone(),
                parse_expr(e.get_ref(), &symbols).map_err(|err| expr_error(src, e, err))?,
            ))
        })
        .collect::<Result<Vec<_>, LocatedError>>()?;
    let time = time(file, src)?;
    let settings = crate::settings::checked(&file.settings, src)?;
    let problem = Problem {
        nodes,
        states,
        controls,
        dynamics,
        time,
        constraints,
        balls,
        between_nodes,
        outputs,
        state_bounds_ctcs: file.state_bounds_ctcs.then_some(CtcsOptions {
            penalty: Penalty::Relu,
            eps: 1e-6,
            group: 0,
        }),
        interval_bounds_sampling: armature_scvx::Sampling::Peak,
        dilation: None,
    };
    Ok((problem, settings))
}

/// `[parameters]` as leaves of the symbol table.
fn parameters(file: &ProblemFile, src: Source<'_>) -> Result<SymbolTable, LocatedError> {
    let mut symbols = SymbolTable::new();
    for (name, v) in &file.parameters {
        let vals = match v.get_ref() {
            Values::One(x) => vec![*x],
            Values::Many(v) => v.clone(),
        };
        if vals.is_empty() || vals.iter().any(|x| !x.is_finite()) {
            return Err(src.error(v, format!("parameter '{name}' needs finite values")));
        }
        let shape = if matches!(v.get_ref(), Values::One(_)) {
            Shape::Scalar
        } else {
            Shape::Vector(vals.len())
        };
        symbols.insert_leaf(&Expr::parameter(name, shape, &vals));
    }
    Ok(symbols)
}

/// `[[states]]` and `[[controls]]`, added to the symbol table.
fn variables(
    file: &ProblemFile,
    symbols: &mut SymbolTable,
    src: Source<'_>,
) -> Result<(Vec<State>, Vec<Control>), LocatedError> {
    let mut states = Vec::new();
    for s in &file.states {
        let name = s.name.get_ref();
        if !(1..=MAX_SIZE).contains(&s.size) {
            return Err(src.error(&s.name, format!("state '{name}': size must be 1 to {MAX_SIZE}")));
        }
        let what = format!("state '{name}'");
        let mut st = State::new(name, s.size).bounds(
            &values(src, &s.min, s.size, f64::NEG_INFINITY, &format!("{what} min"))?,
            &values(src, &s.max, s.size, f64::INFINITY, &format!("{what} max"))?,
        );
        st.initial = conditions(src, &s.initial, s.size, &format!("{what} initial"))?;
        st.terminal = conditions(src, &s.terminal, s.size, &format!("{what} final"))?;
        st.interval_bounds = s.interval_bounds;
        symbols.insert_leaf(&st.expr());
        states.push(st);
    }
    let mut controls = Vec::new();
    for c in &file.controls {
        let name = c.name.get_ref();
        if !(1..=MAX_SIZE).contains(&c.size) {
            return Err(
                src.error(&c.name, format!("control '{name}': size must be 1 to {MAX_SIZE}"))
            );
        }
        let what = format!("control '{name}'");
        let mut ctl = Control::new(name, c.size).bounds(
            &values(src, &c.min, c.size, f64::NEG_INFINITY, &format!("{what} min"))?,
            &values(src, &c.max, c.size, f64::INFINITY, &format!("{what} max"))?,
        );
        if let Some(h) = &c.hold {
            ctl.foh = match h.get_ref().as_str() {
                "foh" => true,
                "zoh" => false,
                other => {
                    return Err(src.error(h, format!("hold '{other}': give \"foh\" or \"zoh\"")));
                }
            };
        }
        symbols.insert_leaf(&ctl.expr());
        controls.push(ctl);
    }
    Ok((states, controls))
}

/// `[[constraints]]`, with the between-nodes parts of those that ask for them.
fn constraints(
    file: &ProblemFile,
    symbols: &SymbolTable,
    nodes: usize,
    variables: (&[State], &[Control]),
    src: Source<'_>,
) -> Result<(Vec<ProblemConstraint>, Vec<BetweenNodes>), LocatedError> {
    let mut constraints = Vec::new();
    let mut between_nodes = Vec::new();
    for c in &file.constraints {
        let mut k =
            parse_constraint(c.expr.get_ref(), symbols).map_err(|e| expr_error(src, &c.expr, e))?;
        if c.ctcs {
            k = k.ctcs();
        }
        if let Some(n) = &c.nodes {
            if c.ctcs {
                return Err(src.error(n, "a continuous-time constraint takes `over`, not `nodes`"));
            }
            k = k.at(n.get_ref());
        }
        if let Some(o) = &c.over {
            let [a, b] = *o.get_ref();
            k = k.over(a, b);
        }
        if let Some(name) = &c.name {
            k = k.named(name.clone());
        }
        k.validate(nodes).map_err(|e| src.error(&c.expr, e.to_string()))?;
        let mut ctcs = CtcsOptions::default();
        if let Some(p) = c.penalty {
            ctcs.penalty = p;
        }
        if let Some(e) = c.eps {
            if !(e.is_finite() && e > 0.0) {
                return Err(src.error(&c.expr, format!("eps {e} must be > 0")));
            }
            ctcs.eps = e;
        }
        if let Some(g) = c.group {
            ctcs.group = g;
        }
        if c.between_nodes {
            between_nodes.push(between(src, c, &k, nodes, variables)?);
        } else if c.activation.is_some() {
            return Err(src.error(&c.expr, "activation applies only with between_nodes = true"));
        }
        constraints.push(ProblemConstraint { constraint: k, ctcs });
    }
    Ok((constraints, between_nodes))
}

/// `[[balls]]`.
fn balls(
    file: &ProblemFile,
    symbols: &SymbolTable,
    nodes: usize,
    src: Source<'_>,
) -> Result<Vec<Ball>, LocatedError> {
    let mut balls = Vec::new();
    for b in &file.balls {
        let g = parse_expr(b.expr.get_ref(), symbols).map_err(|e| expr_error(src, &b.expr, e))?;
        let radius = *b.radius.get_ref();
        if !(radius.is_finite() && radius > 0.0) {
            return Err(src.error(&b.radius, format!("radius {radius} must be > 0")));
        }
        if let Some(k) = b.nodes.get_ref().iter().find(|&&k| k >= nodes) {
            return Err(
                src.error(&b.nodes, format!("node {k} is beyond the last node {}", nodes - 1))
            );
        }
        balls.push(Ball {
            name: b.name.clone().unwrap_or_else(|| b.expr.get_ref().clone()),
            g,
            radius,
            nodes: b.nodes.get_ref().clone(),
        });
    }
    Ok(balls)
}

/// `[time]`: fixed, or free in `[min, max]` with a guess.
fn time(file: &ProblemFile, src: Source<'_>) -> Result<Time, LocatedError> {
    Ok(match (&file.time.fixed, &file.time.max) {
        (Some(t), None) => {
            if !(t.get_ref().is_finite() && *t.get_ref() > 0.0) {
                return Err(src.error(t, "fixed time must be > 0"));
            }
            Time::Fixed(*t.get_ref())
        }
        (None, Some(m)) => {
            let (min, max) = (file.time.min.unwrap_or(0.0), *m.get_ref());
            if !(max.is_finite() && min.is_finite() && 0.0 <= min && min < max) {
                return Err(
                    src.error(m, format!("time bounds [{min}, {max}] must satisfy 0 ≤ min < max"))
                );
            }
            let guess = file.time.guess.unwrap_or(0.5 * (min + max));
            if !(min..=max).contains(&guess) {
                return Err(src.error(m, format!("time guess {guess} is outside [{min}, {max}]")));
            }
            Time::Free { min, max, guess, minimize: file.time.minimize }
        }
        (Some(t), Some(_)) => return Err(src.error(t, "give either fixed or max, not both")),
        (None, None) => return Err(src.error(&file.nodes, "[time] needs fixed or max")),
    })
}

/// The between-nodes part of constraint `c` (parsed as `k`): its `g ≤ 0` over `over`'s
/// segments (default all), which must be an inequality of the states only.
fn between(
    src: Source<'_>,
    c: &ConstraintSpec,
    k: &armature_symbolic::Constraint,
    nodes: usize,
    (states, controls): (&[State], &[Control]),
) -> Result<BetweenNodes, LocatedError> {
    if k.is_equality() {
        return Err(src.error(&c.expr, "a between-nodes constraint must be an inequality"));
    }
    let (first, last) =
        c.over.as_ref().map_or((0, nodes - 1), |o| (o.get_ref()[0], o.get_ref()[1]));
    if first >= last {
        let reason = format!("a between-nodes constraint needs a segment (over [{first}, {last}])");
        return Err(match &c.over {
            Some(o) => src.error(o, reason),
            None => src.error(&c.expr, reason),
        });
    }
    let xs: Vec<Expr> = states.iter().map(State::expr).collect();
    let us: Vec<Expr> = controls.iter().map(Control::expr).collect();
    let function = armature_symbolic::Function::compile(&[k.function().clone()], &[&xs, &us])
        .map_err(|e| src.error(&c.expr, e.to_string()))?;
    let checked = IntervalConstraint {
        name: k.name().to_string(),
        function,
        first,
        last,
        activation: None,
        sampling: armature_scvx::Sampling::Peak,
    };
    if checked.reads_controls(states.iter().map(State::size).sum()) {
        return Err(src.error(
            &c.expr,
            "a between-nodes constraint may read the states only (it reads a control)",
        ));
    }
    if let Some(a) = c.activation.filter(|a| a.is_nan() || *a <= 0.0) {
        return Err(src.error(&c.expr, format!("activation {a} must be > 0")));
    }
    Ok(BetweenNodes {
        name: k.name().to_string(),
        g: k.function().clone(),
        first,
        last,
        activation: c.activation,
        sampling: armature_scvx::Sampling::Peak,
    })
}

/// Whether a TOML text is a problem file (it has `states`) rather than a task file.
pub fn is_problem(text: &str) -> bool {
    text.parse::<toml::Table>().map(|t| t.contains_key("states")).unwrap_or(false)
}

/// A problem-layer error of the problem built from `file`, located at the item it names: a
/// state's or control's `name`, a state's `dynamics`, a constraint's `expr`, `[time]`, a
/// setting; the file's start when it names none of them.
pub fn locate(
    file: &ProblemFile,
    src: Source<'_>,
    e: &armature_scvx::ProblemError,
) -> LocatedError {
    let what = crate::settings::error_subject(e);
    let unquote = |s: &str| s.trim().trim_matches('"').to_string();
    let base = |s: &str| s.split('[').next().unwrap_or(s).to_string();
    let at = if let Some(name) = what.strip_prefix("dynamics of ") {
        let name = base(&unquote(name));
        file.states.iter().find(|s| *s.name.get_ref() == name).map(|s| s.dynamics.span().start)
    } else if let Some(name) = what.strip_prefix("state ") {
        let name = unquote(name);
        file.states.iter().find(|s| *s.name.get_ref() == name).map(|s| s.name.span().start)
    } else if let Some(name) = what.strip_prefix("control ") {
        let name = unquote(name);
        file.controls.iter().find(|c| *c.name.get_ref() == name).map(|c| c.name.span().start)
    } else if let Some(name) = what.strip_prefix("constraint ") {
        let name = unquote(name);
        file.constraints
            .iter()
            .find(|c| c.name.as_deref() == Some(name.as_str()) || *c.expr.get_ref() == name)
            .map(|c| c.expr.span().start)
    } else if what == "time" {
        file.time.max.as_ref().or(file.time.fixed.as_ref()).map(|t| t.span().start)
    } else {
        crate::settings::setting_span(src.text, what)
    };
    src.error_at(at.unwrap_or(0), e.to_string())
}
