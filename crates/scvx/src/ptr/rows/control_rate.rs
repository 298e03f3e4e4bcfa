//! A throwaway row family, compiled for tests only, that shows what adding a family costs:
//! this file and one line in `row_families!`. It limits how fast each control changes,
//! `|u_{k+1,i} − u_{k,i}| ≤ r` on every segment (nonnegative cone, constant coefficients).
//!
//! A real family reads its data from the [`Ocp`](crate::Ocp); this one reads its limit from
//! the test that sets it (per thread, so the crate's other tests see no such rows).

use std::cell::Cell;

use super::{Cone, Placement, RowFamily, Source};

thread_local! {
    /// The limit `r` of this thread's solves (`None`: the family adds no rows).
    static LIMIT: Cell<Option<f64>> = const { Cell::new(None) };
}

/// The control-rate rows.
pub(in crate::ptr) struct ControlRate;

impl RowFamily for ControlRate {
    const CONE: Cone = Cone::Nonnegative;

    fn push(cx: &mut Placement<'_>) {
        let Some(r) = LIMIT.with(Cell::get) else { return };
        let v = cx.v;
        for k in 0..v.nn - 1 {
            for i in 0..v.m {
                for sign in [1.0, -1.0] {
                    cx.rb.entry(v.u(k + 1, i), Source::Const(sign));
                    cx.rb.entry(v.u(k, i), Source::Const(-sign));
                    cx.rb.end_row(r);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Dynamics, Ocp, Ptr, PtrSettings, PtrStatus, TrustRegionUpdate};
    use armature_symbolic::Expr;

    /// Minimum time 0 → 1 m, at rest at both ends, |a| ≤ 1: bang–bang without a rate limit.
    fn double_integrator(nodes: usize) -> Ocp {
        let (p, v, a) = (Expr::variable("p", 1), Expr::variable("v", 1), Expr::variable("a", 1));
        let dynamics = Dynamics::new(&[p, v.clone()], &[a.clone()], &[v, a], &[true]).unwrap();
        Ocp {
            dynamics,
            nodes,
            x_min: vec![-10.0, -10.0],
            x_max: vec![10.0, 10.0],
            u_min: vec![-1.0],
            u_max: vec![1.0],
            x_initial: vec![Some(0.0), Some(0.0)],
            x_final: vec![Some(1.0), Some(0.0)],
            s_min: 0.1,
            s_max: 10.0,
            s_scale: None,
            final_time: (0.0, f64::INFINITY),
            time_weight: 1.0,
            final_cost: vec![],
            increments: vec![],
            nodal: vec![],
            interval_bounds: vec![],
            interval_bounds_sampling: crate::Sampling::Peak,
            interval_constraints: vec![],
        }
    }

    /// The largest control step of a solve with the limit `limit`, and its final time.
    fn solve(limit: Option<f64>) -> (f64, f64) {
        LIMIT.with(|l| l.set(limit));
        let nodes = 21;
        let settings = PtrSettings {
            trust_region: TrustRegionUpdate::Constant,
            lam_vc: 1e2,
            eps_tr: 1e-4,
            ..PtrSettings::default()
        };
        let x: Vec<f64> = (0..nodes).flat_map(|k| [k as f64 / (nodes - 1) as f64, 0.0]).collect();
        let (u, s) = (vec![0.0; nodes], vec![2.0; nodes]);
        let r = Ptr::new(double_integrator(nodes), settings).unwrap().solve(&x, &u, &s).unwrap();
        LIMIT.with(|l| l.set(None));
        assert_eq!(r.status, PtrStatus::Converged, "limit {limit:?}");
        let step = r.u.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max);
        (step, r.final_time)
    }

    #[test]
    fn a_new_family_limits_the_control_rate() {
        let (free_step, free_time) = solve(None);
        assert!(free_step > 0.5, "bang–bang switches a by {free_step} in one segment");
        let (step, time) = solve(Some(0.1));
        assert!(step <= 0.1 + 1e-7, "step {step} over the limit 0.1");
        // Limiting the rate costs time: the unconstrained optimum is 2 s.
        assert!((free_time - 2.0).abs() < 0.05, "{free_time}");
        assert!(time > free_time + 0.05, "{time} vs {free_time}");
    }
}
