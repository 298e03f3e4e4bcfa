//! A caller's judgement of a running solve's iterates: [`Monitor`], which may tell the solve
//! to keep an iterate, and to drop its cost and only restore feasibility — near the current
//! reference or near the kept iterate ([`Steer`]).

use super::*;

/// What a [`Monitor`] tells a running solve after an iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Steer {
    /// Go on as before.
    Continue,
    /// Go on, keeping this iterate (a copy of the reference) as the one to come back to
    /// ([`RestoreFeasibilityFromKept`](Self::RestoreFeasibilityFromKept)); it replaces any
    /// iterate kept before.
    Keep,
    /// Drop the cost: only restore feasibility near the current reference
    /// ([`Ptr::restore_feasibility_only`]). Asked once; later answers are not read.
    RestoreFeasibilityOnly,
    /// Drop the cost and go back to the kept iterate: only restore feasibility near it
    /// ([`Ptr::restore_feasibility_from`]); near the current reference if none was kept.
    /// Asked once, as [`RestoreFeasibilityOnly`](Self::RestoreFeasibilityOnly).
    RestoreFeasibilityFromKept,
}

/// A judgement of a running solve's iterates by the caller's own measure, consulted after
/// every iteration while the solve still minimizes its cost (see
/// [`CompiledProblem::set_monitor`]).
///
/// # Example
/// ```
/// use armature_scvx::{Monitor, Steer};
///
/// // Stop minimizing after 20 iterations, whatever they reached.
/// let monitor = Monitor::new(|it, _trajectory| {
///     if it.iteration >= 20 { Steer::RestoreFeasibilityOnly } else { Steer::Continue }
/// });
/// # let _ = monitor;
/// ```
pub struct Monitor(Box<MonitorFn>);

/// The function a [`Monitor`] calls.
type MonitorFn = dyn FnMut(&Iteration, &Trajectory<'_>) -> Steer + Send;

impl Monitor {
    /// A monitor calling `judge` with each iteration's record and the reference trajectory
    /// after it (the last accepted one).
    pub fn new(judge: impl FnMut(&Iteration, &Trajectory<'_>) -> Steer + Send + 'static) -> Self {
        Monitor(Box::new(judge))
    }

    pub(super) fn judge(&mut self, it: &Iteration, t: &Trajectory<'_>) -> Steer {
        (self.0)(it, t)
    }
}

impl std::fmt::Debug for Monitor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Monitor(..)")
    }
}

impl CompiledProblem {
    /// Sets the monitor that the next solves consult after every iteration while they still
    /// minimize their cost (`None`: none). A solve that a monitor steers to
    /// [`Steer::RestoreFeasibilityOnly`] ends when its trajectory is feasible; its
    /// iterations from then on are marked [`Iteration::feasibility`].
    pub fn set_monitor(&mut self, monitor: Option<Monitor>) {
        self.monitor = monitor;
    }

    /// The PTR loop from `(x, u, s)`: each iteration shown to `observer`, then judged by the
    /// monitor while the cost is on.
    pub(super) fn run(
        &mut self,
        (x, u, s): (&[f64], &[f64], &[f64]),
        mut observer: impl FnMut(&Iteration, &Trajectory<'_>),
    ) -> Result<PtrResult, PtrError> {
        self.ptr.start(x, u, s)?;
        // The iterate a monitor keeps: allocated once, at its first `Keep`.
        let mut kept: Option<[Vec<f64>; 3]> = None;
        loop {
            let it = self.ptr.step()?;
            let mut steer = Steer::Continue;
            if let Some(t) = self.ptr.trajectory() {
                observer(&it, &t);
                if let Some(m) = self.monitor.as_mut().filter(|_| self.ptr.cost_on()) {
                    steer = m.judge(&it, &t);
                }
            }
            if it.status.is_some() {
                break;
            }
            match (steer, &kept) {
                (Steer::Continue, _) => {}
                (Steer::Keep, _) => {
                    if let Some(t) = self.ptr.trajectory() {
                        keep(&mut kept, &t);
                    }
                }
                (Steer::RestoreFeasibilityFromKept, Some([x, u, s])) => {
                    self.ptr.restore_feasibility_from(x, u, s)?;
                }
                (Steer::RestoreFeasibilityOnly | Steer::RestoreFeasibilityFromKept, _) => {
                    self.ptr.restore_feasibility_only()?;
                }
            }
        }
        self.ptr.result().ok_or(PtrError::NotRunning)
    }
}

/// Copies `t`'s states, controls and dilations into `kept` (allocated the first time).
fn keep(kept: &mut Option<[Vec<f64>; 3]>, t: &Trajectory<'_>) {
    match kept {
        Some([x, u, s]) => {
            x.copy_from_slice(t.x);
            u.copy_from_slice(t.u);
            s.copy_from_slice(t.s);
        }
        None => *kept = Some([t.x.to_vec(), t.u.to_vec(), t.s.to_vec()]),
    }
}
