//! The merit function that accepts or rejects a step, and its parts.

use super::*;

/// A trajectory's merit `J`, final time, largest defect and largest nodal violation.
pub(super) type MeritValues = (f64, f64, f64, f64);

/// The Lagrangian merit's shift of the ℓ1 merit for the defects `d` (state rows cycle with
/// period `lam_vc.len()`): per row `(σ − 1)·λ·|d| − ŷ·d`, with the dual `y` clipped to
/// `ŷ ∈ [−σλ, σλ]`. The row's merit term `λ|d| + shift` then lies in `[0, 2σλ|d|]`: never
/// negative, so the merit stays bounded below. With the raw dual it is
/// `σλ|d| − y·d`, which decreases without bound along `sign(y)` wherever `|y| > σλ` — on the
/// seed's collision CTCS row (dual ≈ 2000, price ≈ 2500, σ = 0.5) steps that grew that
/// row's defect were accepted as improvements until the trust region hit its cap, and the
/// run ended at the iteration cap, infeasible.
pub(super) fn lagrangian_shift(d: &[f64], duals: &[f64], lam_vc: &[f64], sigma: f64) -> f64 {
    let n = lam_vc.len();
    d.iter()
        .zip(duals)
        .enumerate()
        .map(|(i, (di, yi))| {
            let l = lam_vc[i % n];
            (sigma - 1.0) * l * di.abs() - yi.clamp(-sigma * l, sigma * l) * di
        })
        .sum()
}

/// The Lagrangian merit's shift of the ℓ1 merit at defects `d` (zero for the exact penalty).
pub(super) fn merit_shift(merit: Merit, d: &[f64], duals: &[f64], lam_vc: &[f64]) -> f64 {
    let Merit::Lagrangian { sigma } = merit else { return 0.0 };
    lagrangian_shift(d, duals, lam_vc, sigma)
}

impl Ptr {
    /// Merit `(J, t_f, max defect, max nodal violation)` of a trajectory (`at`: whether it
    /// is the reference).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn merit(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        d: &Discretization,
        ev: &mut NodalEval,
        (lam_vc, lam_vb): (&[f64], &[f64]),
        at: GridAt,
    ) -> MeritValues {
        let tf = self.final_time(s);
        let l1 = self.defect_price(d, lam_vc);
        let max = d.defect.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let (viol, max_viol) = self.eval_nodal(x, u, ev, lam_vb, false);
        let (pviol, max_pviol) = self.eval_peaks(d, ev, lam_vb, at);
        (self.cost(x, tf) + l1 + viol + pviol, tf, max, max_viol.max(max_pviol))
    }

    /// The final time of the dilations `s` (N).
    pub(super) fn final_time(&self, s: &[f64]) -> f64 {
        let nn = self.ocp.nodes;
        let dtau = 1.0 / (nn - 1) as f64;
        dtau * s[..nn - 1].iter().sum::<f64>()
    }

    /// The merit's price of `d`'s defects, `Σ λ_vc,i·|defect_i|`.
    pub(super) fn defect_price(&self, d: &Discretization, lam_vc: &[f64]) -> f64 {
        let n = self.ocp.dynamics.n_x();
        d.defect.iter().enumerate().map(|(i, x)| lam_vc[i % n] * x.abs()).sum()
    }

    /// The objective: time weight × final time plus the final-state cost; 0 once the cost is
    /// dropped ([`Ptr::restore_feasibility_only`]).
    pub(super) fn cost(&self, x: &[f64], tf: f64) -> f64 {
        if !self.cost_on {
            return 0.0;
        }
        let last = (self.ocp.nodes - 1) * self.ocp.dynamics.n_x();
        self.ocp.time_weight * tf
            + self.ocp.final_cost.iter().map(|&(i, w)| w * x[last + i]).sum::<f64>()
    }
}
