//! The exact-penalty prices a solve ends with, named, and the prices a solve starts from.
//!
//! PTR prices each dynamics row's virtual control (`λ_vc`, per state row) and each
//! buffer (`λ_vb`: a nodal constraint's output at a node, or one bound between the nodes on
//! one segment), doubling a price whenever the subproblem buys that buffer, until it exceeds
//! the row's multiplier. A solve started at the usual prices from a point that another solve
//! already converged — a refined grid's first iterate, say — buys its buffers cheaply again
//! in its first steps and spends its next iterations paying them back. [`Prices`] names each
//! price by the row it prices ([`PricedRow`]), so that a related problem (the same task on
//! another grid) can start from them ([`Ptr::set_starting_prices`]).

use super::*;

/// The row a buffer's price belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PricedRow {
    /// Output `output` of nodal constraint `constraint` ([`Ocp::nodal`]) at `node`; `None`
    /// for a ball, whose one buffer holds its norm.
    Nodal {
        /// Index in [`Ocp::nodal`].
        constraint: usize,
        /// Its node.
        node: usize,
        /// Its output, or `None` for a ball's norm.
        output: Option<usize>,
    },
    /// A bound held between the nodes on `segment` (the rows of one bound on one segment
    /// share one buffer).
    BetweenNodes {
        /// Which bound.
        bound: PeakBound,
        /// The segment (from node `segment` to `segment + 1`).
        segment: usize,
    },
}

/// A bound held between the nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PeakBound {
    /// A state row's upper or lower bound ([`Ocp::interval_bounds`]).
    State {
        /// The state row.
        row: usize,
        /// Its upper bound (else its lower).
        upper: bool,
    },
    /// Output `output` of interval constraint `constraint` ([`Ocp::interval_constraints`]).
    Function {
        /// Index in [`Ocp::interval_constraints`].
        constraint: usize,
        /// Its output.
        output: usize,
    },
}

/// The exact-penalty prices of a solve: per state row its virtual control's, per buffer
/// its row's, and the trust-region weight it ended with.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Prices {
    /// `λ_vc` of each state row (the dynamics' `n_x`).
    pub state_rows: Vec<f64>,
    /// `λ_vb` of each buffer, with the row it prices.
    pub rows: Vec<(PricedRow, f64)>,
    /// The trust-region weight `λ_tr` of the last iteration.
    pub trust_region: f64,
}

/// Prices a solve starts from (see [`Ptr::set_starting_prices`]): per buffer, in this
/// problem's buffer order.
#[derive(Debug, Clone, Default)]
pub(super) struct StartingPrices {
    pub(super) state_rows: Vec<f64>,
    pub(super) buffers: Vec<Option<f64>>,
    pub(super) trust_region: Option<f64>,
}

impl Ptr {
    /// The row each buffer prices, in buffer order (the nodal buffers, then the peak rows').
    pub fn priced_rows(&self) -> Vec<PricedRow> {
        let mut rows: Vec<PricedRow> = self
            .buffers
            .iter()
            .map(|&(eval, constraint, output)| PricedRow::Nodal {
                constraint,
                node: self.nodal_blocks[eval].1,
                output,
            })
            .collect();
        let mut peaks: Vec<Option<PricedRow>> = vec![None; self.peak_buffers()];
        for p in &self.peaks {
            let bound = match p.of {
                PeakOf::State(row) => PeakBound::State { row, upper: p.sign > 0.0 },
                PeakOf::Function { c, out } => PeakBound::Function { constraint: c, output: out },
            };
            peaks[p.buffer] = Some(PricedRow::BetweenNodes { bound, segment: p.seg });
        }
        // Every peak buffer has its rows (`rows/peaks.rs` numbers them as it places rows).
        rows.extend(peaks.into_iter().flatten());
        rows
    }

    /// The prices the running (or last) solve holds, named; `None` before a first solve.
    pub fn prices(&self) -> Option<Prices> {
        self.state.as_ref().map(|st| self.prices_of(st))
    }

    /// The prices `st` holds, named.
    pub(super) fn prices_of(&self, st: &Iterate) -> Prices {
        let rows = self.priced_rows().into_iter().zip(st.lam_vb.iter().copied()).collect();
        Prices { state_rows: st.lam_vc.clone(), rows, trust_region: st.lam_tr }
    }

    /// The prices the next solves start from instead of the settings' `lam_vc`, `lam_vb`
    /// and `lam_tr`: each state row's `state_rows` entry (when `state_rows` has one per
    /// state row), each buffer's `price(row)` where it gives one (never below `lam_vb`), and
    /// `trust_region` (within `lam_tr_min`..`lam_tr_max`) when given. `price` is asked once
    /// per buffer, here. Called with no prices and `None`, it restores the settings'.
    pub fn set_starting_prices(
        &mut self,
        state_rows: &[f64],
        price: impl Fn(PricedRow) -> Option<f64>,
        trust_region: Option<f64>,
    ) {
        let usable = |p: &f64| p.is_finite() && *p > 0.0;
        let n = self.ocp.dynamics.n_x();
        self.starting = StartingPrices {
            state_rows: if state_rows.len() == n && state_rows.iter().all(usable) {
                state_rows.to_vec()
            } else {
                Vec::new()
            },
            buffers: self.priced_rows().into_iter().map(|r| price(r).filter(usable)).collect(),
            trust_region: trust_region.filter(usable),
        };
    }

    /// The starting prices into a new solve's weights (after the settings' are set).
    pub(super) fn apply_starting_prices(&self, st: &mut Iterate) {
        let s = &self.starting;
        if !s.state_rows.is_empty() {
            for (w, p) in st.lam_vc.iter_mut().zip(&s.state_rows) {
                *w = p.max(self.settings.lam_vc).min(self.settings.lam_vc_max);
            }
        }
        for (w, p) in st.lam_vb.iter_mut().zip(&s.buffers) {
            if let Some(p) = p {
                *w = p.max(self.settings.lam_vb).min(self.settings.lam_vc_max);
            }
        }
        if let Some(t) = s.trust_region {
            st.lam_tr = t.clamp(self.settings.lam_tr_min, self.settings.lam_tr_max);
        }
    }
}
