//! The named variables of a [`Problem`]: states, controls, boundary conditions and time.

use super::*;

/// A boundary condition of one state component.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Boundary {
    /// Fixed to this value.
    Fixed(f64),
    /// Free.
    Free,
    /// Free, and its final value is minimized (final conditions only).
    Minimize,
    /// Free, and its final value is maximized (final conditions only).
    Maximize,
}

/// A named state vector with bounds, boundary conditions and an optional guess.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// The name (the symbolic variable's, and the key in the [`Solution`]).
    pub name: String,
    /// Lower bounds (−∞ for none), one per component.
    pub min: Vec<f64>,
    /// Upper bounds (+∞ for none).
    pub max: Vec<f64>,
    /// Initial conditions, one per component.
    pub initial: Vec<Boundary>,
    /// Final conditions, one per component.
    pub terminal: Vec<Boundary>,
    /// Guess, N × size row-major (`None`: the straight line between the boundary values).
    pub guess: Option<Vec<f64>>,
    /// Also enforce the bounds between the nodes, at each segment's peak on the integration
    /// grid ([`Ocp::interval_bounds`]): for bounds the motion rides, whose CTCS integral alone
    /// gives the subproblems no gradient where the trajectory touches them (at every grid
    /// point instead under [`Sampling::GridPoints`](crate::Sampling::GridPoints), which also
    /// takes the state out of [`Problem::state_bounds_ctcs`](crate::Problem::state_bounds_ctcs)).
    /// Default false.
    pub interval_bounds: bool,
}

impl State {
    /// A free, unbounded state of `size` components.
    pub fn new(name: &str, size: usize) -> State {
        State {
            name: name.to_string(),
            min: vec![f64::NEG_INFINITY; size],
            max: vec![f64::INFINITY; size],
            initial: vec![Boundary::Free; size],
            terminal: vec![Boundary::Free; size],
            guess: None,
            interval_bounds: false,
        }
    }

    /// Number of components.
    pub fn size(&self) -> usize {
        self.min.len()
    }

    /// The symbolic variable of this state.
    pub fn expr(&self) -> Expr {
        Expr::variable(&self.name, self.size())
    }

    /// With bounds.
    pub fn bounds(mut self, min: &[f64], max: &[f64]) -> Self {
        (self.min, self.max) = (min.to_vec(), max.to_vec());
        self
    }

    /// With a fixed initial value.
    pub fn initial_value(mut self, v: &[f64]) -> Self {
        self.initial = v.iter().map(|&x| Boundary::Fixed(x)).collect();
        self
    }

    /// With a fixed final value.
    pub fn final_value(mut self, v: &[f64]) -> Self {
        self.terminal = v.iter().map(|&x| Boundary::Fixed(x)).collect();
        self
    }

    /// With per-component final conditions.
    pub fn final_conditions(mut self, b: &[Boundary]) -> Self {
        self.terminal = b.to_vec();
        self
    }

    /// With a guess (N × size, row-major).
    pub fn guess(mut self, g: Vec<f64>) -> Self {
        self.guess = Some(g);
        self
    }

    /// With its bounds also enforced between the nodes ([`State::interval_bounds`]).
    pub fn with_interval_bounds(mut self) -> Self {
        self.interval_bounds = true;
        self
    }
}

/// A named control vector with bounds and an optional guess.
#[derive(Debug, Clone, PartialEq)]
pub struct Control {
    /// The name.
    pub name: String,
    /// Lower bounds (−∞ for none).
    pub min: Vec<f64>,
    /// Upper bounds (+∞ for none).
    pub max: Vec<f64>,
    /// First-order hold (true, the default) or zero-order hold.
    pub foh: bool,
    /// Guess, N × size row-major (`None`: zero, clamped into the bounds).
    pub guess: Option<Vec<f64>>,
    /// Time-scaled: the solver works on `w = s·u` ([`Dynamics::time_scaled`](crate::Dynamics::time_scaled)).
    /// Bounds, guess and solution stay in the physical `u`. Default false.
    pub time_scaled: bool,
}

impl Control {
    /// An unbounded first-order-hold control of `size` components.
    pub fn new(name: &str, size: usize) -> Control {
        Control {
            name: name.to_string(),
            min: vec![f64::NEG_INFINITY; size],
            max: vec![f64::INFINITY; size],
            foh: true,
            guess: None,
            time_scaled: false,
        }
    }

    /// Number of components.
    pub fn size(&self) -> usize {
        self.min.len()
    }

    /// The symbolic variable of this control.
    pub fn expr(&self) -> Expr {
        Expr::variable(&self.name, self.size())
    }

    /// With bounds.
    pub fn bounds(mut self, min: &[f64], max: &[f64]) -> Self {
        (self.min, self.max) = (min.to_vec(), max.to_vec());
        self
    }

    /// Time-scaled ([`Control::time_scaled`](Control#structfield.time_scaled)).
    pub fn with_time_scaling(mut self) -> Self {
        self.time_scaled = true;
        self
    }

    /// With a guess (N × size, row-major).
    pub fn guess(mut self, g: Vec<f64>) -> Self {
        self.guess = Some(g);
        self
    }
}

/// The final time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Time {
    /// Fixed duration (s).
    Fixed(f64),
    /// Free within `[min, max]` (s), starting from `guess`, minimized or not.
    Free {
        /// Lower bound (0 for none).
        min: f64,
        /// Upper bound (finite: it also bounds the per-segment dilations).
        max: f64,
        /// Initial guess.
        guess: f64,
        /// Minimize the final time.
        minimize: bool,
    },
}
