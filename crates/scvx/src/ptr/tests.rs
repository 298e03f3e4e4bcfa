//! Unit tests of the PTR internals.

use super::merit::lagrangian_shift;
use super::quasi_newton::damped_bfgs;
use crate::Dynamics;
use armature_symbolic::{Expr, Function};
use proptest::prelude::*;

/// A double integrator p' = v, v' = a (|a| ≤ 1, |p| ≤ 10, |v| ≤ `v_max`) from rest at 0
/// to `x_final` on `nodes` nodes, in minimum time, with an interval constraint `g(p, v)`
/// on every segment and interval bounds on the listed state rows.
fn double_integrator(
    nodes: usize,
    v_max: f64,
    x_final: [Option<f64>; 2],
    g: impl FnOnce(&Expr, &Expr) -> Expr,
    interval_bounds: Vec<usize>,
) -> super::Ocp {
    let (p, v, a) = (Expr::variable("p", 1), Expr::variable("v", 1), Expr::variable("a", 1));
    let function =
        Function::compile(&[g(&p, &v)], &[&[p.clone(), v.clone()], &[a.clone()]]).unwrap();
    let dynamics = Dynamics::new(&[p, v.clone()], &[a.clone()], &[v, a], &[true]).unwrap();
    super::Ocp {
        dynamics,
        nodes,
        x_min: vec![-10.0, -v_max],
        x_max: vec![10.0, v_max],
        u_min: vec![-1.0],
        u_max: vec![1.0],
        x_initial: vec![Some(0.0), Some(0.0)],
        x_final: x_final.to_vec(),
        s_min: 0.1,
        s_max: 10.0,
        s_scale: None,
        final_time: (0.0, f64::INFINITY),
        time_weight: 1.0,
        final_cost: vec![],
        increments: vec![],
        nodal: vec![],
        interval_bounds,
        interval_bounds_sampling: crate::Sampling::Peak,
        interval_constraints: vec![super::IntervalConstraint {
            name: "g".into(),
            function,
            first: 0,
            last: nodes - 1,
            activation: None,
            sampling: crate::Sampling::Peak,
        }],
    }
}

/// The interval values kept for the reference (`NodalEval::fgrid_reference`) are, bit
/// for bit, what evaluating them at the reference gives: after every step of a solve of
/// a double integrator with a nonlinear interval constraint, accepted or rejected.
#[test]
fn interval_values_kept_for_the_reference_are_its_own() {
    use super::{GridAt, Ptr, PtrSettings};
    // v² + 0.3·sin(p) ≤ 0.25 between the nodes of every segment, 0 → 1 m at rest.
    let nodes = 11;
    let g = |p: &Expr, v: &Expr| &(v * v) + &(&p.sin() * 0.3) - 0.25;
    let ocp = double_integrator(nodes, 10.0, [Some(1.0), Some(0.0)], g, vec![]);
    let mut ptr =
        Ptr::new(ocp, PtrSettings { max_iterations: 80, ..PtrSettings::default() }).unwrap();
    let x: Vec<f64> = (0..nodes).flat_map(|k| [k as f64 / (nodes - 1) as f64, 0.0]).collect();
    ptr.start(&x, &vec![0.0; nodes], &vec![3.0; nodes]).unwrap();
    let (mut kept, mut rejected) = (0, 0);
    loop {
        let it = ptr.step().unwrap();
        rejected += usize::from(!it.accepted);
        let st = ptr.state.as_ref().unwrap();
        if st.ev.fgrid_reference {
            let mut fresh = ptr.iterate().ev;
            ptr.eval_interval(&st.dbar, &mut fresh, GridAt::Other);
            assert_eq!(st.ev.fgrid, fresh.fgrid, "iteration {}", it.iteration);
            kept += 1;
        }
        if it.status.is_some() {
            break;
        }
    }
    // Both paths: accepted steps hand their values on, rejected ones must not.
    assert!(kept > 3 && rejected > 0, "kept at {kept} references, {rejected} rejections");
}

/// The interval rows' coefficients are the derivatives of their peaks: central
/// differences of the peak value in every column of the row (the envelope theorem holds
/// the vertex's weights), on a double integrator whose velocity peaks inside segments —
/// for the velocity's bounds and for a nonlinear interval constraint of both states.
#[test]
fn peak_row_coefficients_are_derivatives_of_the_peak() {
    let (checked, checked_g) = row_coefficients_against_differences(crate::Sampling::Peak);
    assert!(checked >= 8, "{checked} coefficients of refined (interior) peaks checked");
    assert!(checked_g >= 8, "{checked_g} coefficients of refined function peaks checked");
}

/// The same with a row at every grid point ([`crate::Sampling::GridPoints`]): each row's
/// coefficients are the derivatives of its local peak (the parabola's vertex within half a
/// grid step, or the point's value, plus the cubic margin), away from the margin's kinks.
#[test]
fn grid_point_row_coefficients_are_derivatives_of_their_local_peaks() {
    let (checked, checked_g) = row_coefficients_against_differences(crate::Sampling::GridPoints);
    assert!(checked >= 8, "{checked} coefficients of refined (interior) local peaks checked");
    assert!(checked_g >= 8, "{checked_g} coefficients of refined function rows checked");
}

/// Checks every interval row's coefficients against central differences of its value;
/// returns how many coefficients of parabola-refined rows (of state bounds, of functions)
/// were checked.
fn row_coefficients_against_differences(sampling: crate::Sampling) -> (usize, usize) {
    use super::{PeakOf, Ptr, PtrSettings, Source};
    use crate::DiscretizationSettings;
    // g = [v² + 0.3·p − 0.2, −v·(1 + sin²p)] ≤ 0 on segments 0..3.
    let g = |p: &Expr, v: &Expr| {
        Expr::concat(&[&(v * v) + &(p * 0.3) - 0.2, -(v * &(&(&p.sin() * &p.sin()) + 1.0))])
    };
    let mut ocp = double_integrator(4, 0.5, [None, None], g, vec![1]);
    ocp.interval_bounds_sampling = sampling;
    ocp.interval_constraints[0].sampling = sampling;
    let ptr = Ptr::new(ocp, PtrSettings::default()).unwrap();
    let settings = DiscretizationSettings::default();
    // z = [x (4×2) | u (4) | s (4)]: alternating accelerations make the velocity peak
    // (up) or dip (down) inside every segment.
    let mut z = vec![0.0, 0.2, 0.3, 0.1, 0.5, -0.3, 0.6, 0.2];
    z.extend([1.0, -0.6, 0.8, -0.9]);
    z.extend([1.2, 0.9, 1.5, 1.5]);
    let disc = |z: &[f64]| {
        let mut ws = ptr.ocp.dynamics.workspace();
        let mut d = ptr.output();
        ptr.ocp
            .dynamics
            .discretize(&z[..8], &z[8..12], &z[12..], &settings, &mut ws, &mut d)
            .unwrap();
        d
    };
    let peak = |z: &[f64], pk| {
        let d = disc(z);
        let mut ev = ptr.iterate().ev;
        ptr.eval_interval(&d, &mut ev, super::GridAt::Other);
        ptr.peak(&d, &ev, pk)
    };
    let d = disc(&z);
    let mut ev = ptr.iterate().ev;
    ptr.fill_peaks(&d, &mut ev, super::GridAt::Other);
    let h = 1e-6;
    let (mut checked, mut checked_g, mut kinks) = (0, 0, 0);
    // ±v and g's 2 outputs on 3 segments: at each peak, or at each segment's 11 grid points.
    let places = if sampling == crate::Sampling::Peak { 3 } else { 33 };
    assert_eq!(ptr.peaks.len(), places * (2 + 2));
    for pk in &ptr.peaks {
        let (_, _, w) = peak(&z, pk);
        // Refined: a parabola's vertex between points, or a cubic margin.
        let interior = w.iter().filter(|&&w| w != 0.0).count() >= 3;
        for q in pk.src.clone() {
            let col = (0..12 + 4)
                .find(|&c| {
                    (ptr.a_colptr[c]..ptr.a_colptr[c + 1])
                        .any(|i| matches!(ptr.sources[i], Source::Peak(k) if k == q))
                })
                .unwrap();
            let (mut zp, mut zm) = (z.clone(), z.clone());
            zp[col] += h;
            zm[col] -= h;
            let (vp, vm) = (peak(&zp, pk), peak(&zm, pk));
            // Where the cubic margin switches its window (or sign) within ±h, the row has a
            // kink and no derivative: skipped.
            if vp.2.iter().zip(&w).chain(vm.2.iter().zip(&w)).any(|(a, b)| (a - b).abs() > 1e-3) {
                kinks += 1;
                continue;
            }
            let fd = (vp.0 - vm.0) / (2.0 * h);
            let an = ev.peak_vals[q];
            assert!(
                (fd - an).abs() < 1e-6 * (1.0 + an.abs()),
                "segment {} {:?} sign {} w {w:?} col {col}: {an} vs {fd}",
                pk.seg,
                pk.of,
                pk.sign
            );
            if matches!(pk.of, PeakOf::Function { .. }) {
                checked_g += usize::from(interior);
            } else {
                checked += usize::from(interior);
            }
        }
    }
    assert!(kinks <= 4, "{kinks} coefficients at kinks");
    (checked, checked_g)
}

/// `local_peak`: the vertex of the parabola through a grid point and its neighbours, within
/// half a step (the end points: half a step inward); the point's own value where the parabola
/// is convex.
#[test]
fn local_peaks_are_vertices_within_half_a_step() {
    use super::evaluate::{Stencil, local_peak};
    let pts = 6;
    let weights_sum = |w: Stencil| w.iter().sum::<f64>();
    // A concave parabola with its vertex 0.3 past point 2: exact.
    let (v, first, w) = local_peak(pts, 2, |j| 1.0 - (j as f64 - 2.3).powi(2));
    assert!((v - 1.0).abs() < 1e-12 && first == 0 && (weights_sum(w) - 1.0).abs() < 1e-12);
    // Its vertex 1.9 past point 2: clamped at 2.5.
    let (v, _, _) = local_peak(pts, 2, |j| 1.0 - (j as f64 - 3.9).powi(2));
    assert!((v - (1.0 - 1.4f64.powi(2))).abs() < 1e-12, "{v}");
    // Convex, flat and end points: the value there.
    assert!((local_peak(pts, 2, |j| (j as f64 - 2.3).powi(2)).0 - 0.09).abs() < 1e-12);
    assert_eq!(local_peak(pts, 3, |_| 0.7).0, 0.7);
    assert_eq!(local_peak(pts, 0, |j| -(j as f64)).0, 0.0);
    let (v, first, w) = local_peak(pts, pts - 1, |j| j as f64);
    assert!((v - 5.0).abs() < 1e-12 && first == pts - 4 && (weights_sum(w) - 1.0).abs() < 1e-12);
    // The end points reach half a step inward: a vertex 0.3 past point 0 is caught by the
    // first point's row, one 0.3 before the last point by the last one's, exactly.
    let (v, first, _) = local_peak(pts, 0, |j| 1.0 - (j as f64 - 0.3).powi(2));
    assert!((v - 1.0).abs() < 1e-12 && first == 0, "{v}");
    let (v, _, _) = local_peak(pts, pts - 1, |j| 1.0 - (j as f64 - 4.7).powi(2));
    assert!((v - 1.0).abs() < 1e-12, "{v}");
    // Beyond half a step: the cell's inner end.
    let (v, _, _) = local_peak(pts, 0, |j| 1.0 - (j as f64 - 0.9).powi(2));
    assert!((v - (1.0 - 0.4f64.powi(2))).abs() < 1e-12, "{v}");
}

/// `h` (d×d) times `v`.
fn mul(h: &[f64], v: &[f64]) -> Vec<f64> {
    let d = v.len();
    (0..d).map(|a| (0..d).map(|b| h[a * d + b] * v[b]).sum()).collect()
}

/// Positive definite by Cholesky.
fn positive_definite(h: &[f64], d: usize) -> bool {
    let mut l = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i * d + k] * l[j * d + k]).sum();
            if i == j {
                let v = h[i * d + i] - s;
                if v <= 0.0 {
                    return false;
                }
                l[i * d + i] = v.sqrt();
            } else {
                l[i * d + j] = (h[i * d + j] - s) / l[j * d + j];
            }
        }
    }
    true
}

proptest! {
    /// For a cubic `g` on a segment's grid, the grid points' rows (`local_peak`: their
    /// parabolas and the cubic margin) bound `g` everywhere on the segment: where every row
    /// holds `≤ 0`, so does `g` between the points. Each row's value is its weights' sum
    /// `Σ w_i g_i`, so its gradient is theirs.
    #[test]
    fn grid_point_rows_bound_a_cubic_between_the_points(
        c in prop::array::uniform4(-1.0f64..1.0),
        pts in 4usize..9,
    ) {
        use super::evaluate::local_peak;
        let g = |t: f64| c[0] + c[1] * t + c[2] * t * t + c[3] * t * t * t;
        let mut rows = f64::MIN;
        for j in 0..pts {
            let (row, first, w) = local_peak(pts, j, |i| g(i as f64));
            let sum: f64 = w.iter().enumerate().filter(|(_, w)| **w != 0.0)
                .map(|(i, w)| w * g((first + i) as f64)).sum();
            prop_assert!((row - sum).abs() < 1e-12);
            prop_assert!(w.iter().enumerate().all(|(i, w)| *w == 0.0 || first + i < pts));
            rows = rows.max(row);
        }
        let last = (pts - 1) as f64;
        let peak = (0..=2000).map(|i| g(last * i as f64 / 2000.0)).fold(f64::MIN, f64::max);
        prop_assert!(rows >= peak - 1e-12, "rows {rows} below the segment's peak {peak}");
    }

    /// For a cubic `g` on a segment's grid, the segment's peak row (`peak_of`: the parabola
    /// around the discrete maximum and the cubic margin) bounds `g` everywhere within a step
    /// of the parabola's centre, and its value is its weights' sum `Σ w_i g_i`.
    #[test]
    fn the_peak_row_bounds_a_cubic_around_the_discrete_maximum(
        c in prop::array::uniform4(-1.0f64..1.0),
        pts in 4usize..9,
    ) {
        use super::evaluate::peak_of;
        let g = |t: f64| c[0] + c[1] * t + c[2] * t * t + c[3] * t * t * t;
        let (row, first, w) = peak_of(pts, |i| g(i as f64));
        let sum: f64 = w.iter().enumerate().filter(|(_, w)| **w != 0.0)
            .map(|(i, w)| w * g((first + i) as f64)).sum();
        prop_assert!((row - sum).abs() < 1e-12);
        prop_assert!(w.iter().enumerate().all(|(i, w)| *w == 0.0 || first + i < pts));
        let best = (0..pts).fold(0, |b, j| if g(j as f64) > g(b as f64) { j } else { b });
        let centre = best.clamp(1, pts - 2) as f64;
        let near = (0..=1000).map(|i| g(centre - 1.0 + 2.0 * i as f64 / 1000.0));
        let peak = near.fold(f64::MIN, f64::max);
        prop_assert!(row >= peak - 1e-12, "row {row} below the peak {peak} near the maximum");
    }

    /// Each row's Lagrangian-merit term `λ|d| + shift` lies in `[0, 2σλ|d|]` whatever the
    /// dual (a dual beyond σλ is clipped), and where `|y| ≤ σλ` the shift is the unclipped
    /// `(σ − 1)λ|d| − y·d`.
    #[test]
    fn the_lagrangian_merit_prices_every_defect_nonnegatively(
        rows in prop::collection::vec((-1.0f64..1.0, -5.0f64..5.0, 0.1f64..4.0), 1..12),
        sigma in 0.0f64..=1.0,
    ) {
        for &(d, y, lam) in &rows {
            let shift = lagrangian_shift(&[d], &[y], &[lam], sigma);
            let term = lam * d.abs() + shift;
            let tol = 1e-12 * (1.0 + lam * d.abs());
            prop_assert!(term >= -tol && term <= 2.0 * sigma * lam * d.abs() + tol, "{term}");
            if y.abs() <= sigma * lam {
                let raw = (sigma - 1.0) * lam * d.abs() - y * d;
                prop_assert!((shift - raw).abs() <= tol);
            }
        }
        // Rows cycle through the per-state prices.
        let (d, y): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| (r.0, r.1)).unzip();
        let lam: Vec<f64> = rows.iter().map(|r| r.2).collect();
        let twice: Vec<f64> = d.iter().chain(&d).copied().collect();
        let yy: Vec<f64> = y.iter().chain(&y).copied().collect();
        let one = lagrangian_shift(&d, &y, &lam, sigma);
        prop_assert!((lagrangian_shift(&twice, &yy, &lam, sigma) - 2.0 * one).abs() <= 1e-9);
    }

    /// Undamped (positive curvature) the update satisfies the secant equation H⁺s = y;
    /// with any pair it stays symmetric positive definite.
    #[test]
    fn damped_bfgs_keeps_the_secant_equation_and_positive_definiteness(
        diag in prop::collection::vec(0.1f64..10.0, 4),
        s in prop::collection::vec(-1.0f64..1.0, 4),
        y in prop::collection::vec(-1.0f64..1.0, 4),
    ) {
        let d = 4;
        prop_assume!(s.iter().map(|v| v * v).sum::<f64>() > 1e-3);
        let mut h = vec![0.0; d * d];
        for (a, v) in diag.iter().enumerate() {
            h[a * d + a] = *v;
        }
        let hs0 = mul(&h, &s);
        let shs: f64 = s.iter().zip(&hs0).map(|(a, b)| a * b).sum();
        let sy: f64 = s.iter().zip(&y).map(|(a, b)| a * b).sum();
        let (mut hs, mut r) = (vec![0.0; d], vec![0.0; d]);
        prop_assert!(damped_bfgs(&mut h, &s, &y, &mut hs, &mut r));
        for a in 0..d {
            for b in 0..d {
                prop_assert!((h[a * d + b] - h[b * d + a]).abs() < 1e-9);
            }
        }
        prop_assert!(positive_definite(&h, d), "{h:?}");
        // H⁺s = r always; r = y when sᵀy ≥ 0.2·sᵀHs.
        let hs1 = mul(&h, &s);
        for a in 0..d {
            prop_assert!((hs1[a] - r[a]).abs() < 1e-8 * (1.0 + r[a].abs()));
            if sy >= 0.2 * shs {
                prop_assert!((hs1[a] - y[a]).abs() < 1e-8 * (1.0 + y[a].abs()));
            }
        }
    }
}

#[test]
fn damped_bfgs_refuses_a_zero_step() {
    let mut h = vec![1.0, 0.0, 0.0, 1.0];
    let (mut hs, mut r) = (vec![0.0; 2], vec![0.0; 2]);
    assert!(!damped_bfgs(&mut h, &[0.0, 0.0], &[1.0, 1.0], &mut hs, &mut r));
    assert_eq!(h, vec![1.0, 0.0, 0.0, 1.0]);
}

/// A nodal constraint `f` of the double integrator's `groups` (`[p, v], [a]`) at `nodes`.
fn nodal_constraint(
    name: &str,
    f: Expr,
    groups: &[&[Expr]],
    nodes: Vec<usize>,
    kind: super::NodalKind,
) -> super::NodalConstraint {
    super::NodalConstraint {
        name: name.into(),
        function: Function::compile(&[f], groups).unwrap(),
        nodes,
        kind,
        output_names: vec![],
    }
}

/// The double integrator made nonlinear (`v̇ = a − ½·sin(p)·v`), with the interval constraint
/// `v² + 0.3·sin p − 0.25 ≤ 0` on the `intervals` segments, an inequality `ineq(p, v, a) ≤ 0`
/// at nodes 1 and 2 and a ball `‖(p·v, cos p − v²)‖ ≤ 0.5` at node 3: curvature in every row
/// kind.
fn curved_problem(
    nodes: usize,
    intervals: Vec<usize>,
    ineq: impl Fn(&Expr, &Expr, &Expr) -> Expr,
) -> super::Ocp {
    use super::NodalKind;
    let g = |p: &Expr, v: &Expr| &(v * v) + &(&p.sin() * 0.3) - 0.25;
    let mut ocp = double_integrator(nodes, 10.0, [None, None], g, intervals);
    let (p, v, a) = (Expr::variable("p", 1), Expr::variable("v", 1), Expr::variable("a", 1));
    let vdot = &a - &(&(&p.sin() * &v) * 0.5);
    ocp.dynamics =
        Dynamics::new(&[p.clone(), v.clone()], &[a.clone()], &[v.clone(), vdot], &[true]).unwrap();
    let groups: &[&[Expr]] = &[&[p.clone(), v.clone()], &[a.clone()]];
    let ball = Expr::concat(&[&p * &v, &p.cos() - &(&v * &v)]);
    let nodal = |name: &str, f: Expr, nodes: Vec<usize>, kind| {
        nodal_constraint(name, f, groups, nodes, kind)
    };
    ocp.nodal = vec![
        nodal("ineq", ineq(&p, &v, &a), vec![1, 2], NodalKind::Inequality),
        nodal("ball", ball, vec![3], NodalKind::Ball { radius: 0.5 }),
    ];
    ocp
}

/// The exact curvature blocks are the Lagrangian's second derivatives, as the subproblem
/// assembles them (every column placed, every sign): `Σ_e H_e·s` equals the directional
/// derivative of `Aᵀy` — central differences of the subproblem's own constraint
/// coefficients along `s` — over the dynamics rows (nonlinear dynamics, dilation) and the
/// nodal rows (an inequality with two outputs on two nodes, a ball), for random duals
/// (zero on the peak rows, whose curvature has its own test).
#[test]
fn exact_curvature_blocks_are_the_lagrangians_second_derivatives() {
    use super::{Ptr, PtrSettings};
    let nodes = 4;
    let ineq =
        |p: &Expr, v: &Expr, a: &Expr| Expr::concat(&[&(&(p * p) + &(v * a)) - 1.0, &p.sin() * v]);
    let ocp = curved_problem(nodes, vec![], ineq);
    let mut settings = PtrSettings { exact_hessian: true, ..PtrSettings::default() };
    settings.discretization.substeps = 40;
    let mut ptr = Ptr::new(ocp, settings).unwrap();
    let (u0, s0, vp0, _) = ptr.layout();
    let z: Vec<f64> = (0..vp0)
        .map(|i| if i >= s0 { 1.0 + 0.2 * (i as f64).cos() } else { (0.7 * i as f64).sin() })
        .collect();
    let dir: Vec<f64> = (0..vp0).map(|i| (1.3 * i as f64 + 0.4).cos()).collect();
    // The subproblem's coefficients `A(z)` (its `nz` values) at a point.
    let coefficients = |ptr: &mut Ptr, z: &[f64]| {
        let mut st = ptr.iterate();
        ptr.linearize(z, &mut st.dbar).unwrap();
        ptr.eval_nodal(&z[..u0], &z[u0..s0], &mut st.ev, &st.lam_vb, true);
        ptr.fill_peaks(&st.dbar, &mut st.ev, super::GridAt::Other);
        let peak_vals = st.ev.peak_vals.clone();
        super::fill_values(&ptr.sources, &st.dbar, &st.ev, &peak_vals, &mut st.nz);
        st.nz
    };
    let h = 1e-5;
    let shifted =
        |sign: f64| -> Vec<f64> { z.iter().zip(&dir).map(|(z, d)| z + sign * h * d).collect() };
    let (zp, zm) = (shifted(1.0), shifted(-1.0));
    let (np, nm) = (coefficients(&mut ptr, &zp), coefficients(&mut ptr, &zm));
    let mut st = ptr.iterate();
    ptr.linearize(&z, &mut st.dbar).unwrap();
    (st.xb, st.ub, st.sb) = (z[..u0].to_vec(), z[u0..s0].to_vec(), z[s0..vp0].to_vec());
    for (i, y) in st.duals.iter_mut().enumerate() {
        *y = (2.1 * i as f64 + 0.3).sin();
    }
    // The peak rows' curvature leaves out the flow's own term (checked on its own below).
    for p in &ptr.peaks {
        st.duals[p.row] = 0.0;
    }
    ptr.exact_curvature(&mut st);
    let mut model = vec![0.0; vp0];
    for (el, hb) in ptr.elements.iter().zip(&st.curv.exact) {
        let d = el.cols.len();
        for (a, &ca) in el.cols.iter().enumerate() {
            model[ca] += (0..d).map(|b| hb[a * d + b] * dir[el.cols[b]]).sum::<f64>();
        }
    }
    let (mut worst, mut scale, mut nodal_rows) = (0.0f64, 0.0f64, 0);
    for (c, m) in model.iter().enumerate() {
        let fd: f64 = (ptr.a_colptr[c]..ptr.a_colptr[c + 1])
            .filter(|&q| ptr.exact.exact_rows[ptr.a_rowval[q]])
            .map(|q| st.duals[ptr.a_rowval[q]] * (np[q] - nm[q]) / (2.0 * h))
            .sum();
        worst = worst.max((m - fd).abs());
        scale = scale.max(fd.abs());
    }
    for nr in &ptr.nodal_rows {
        nodal_rows += usize::from(ptr.exact.exact_rows[nr.row]);
    }
    assert_eq!(nodal_rows, 2 * 2 + 2, "every nodal row is an exact one");
    assert!(scale > 0.1, "a curvature worth checking: {scale}");
    assert!(worst <= 1e-5 * scale, "H·s off by {worst:e} (scale {scale:e})");
}

/// The second-order correction's shift of the right-hand sides, `b′ − b = h(z̄ + Δz) −
/// (b − A·Δz)`, is the error of the subproblem's linear model of each row, so it shrinks
/// with the square of the step: halving `Δz` quarters it on the dynamics rows (nonlinear
/// dynamics), on the nodal rows (an inequality and a ball's cone) and on the peak rows. A
/// sign slip in any row kind would leave a first-order shift (a ratio of 2).
#[test]
fn correction_shifts_are_second_order_in_the_step() {
    use super::{Ptr, PtrSettings};
    let nodes = 5;
    let ocp = curved_problem(nodes, vec![1], |p, v, a| &(&(p * p) + &(v * a)) - 1.0);
    let settings = PtrSettings { second_order_correction: true, ..PtrSettings::default() };
    let mut ptr = Ptr::new(ocp, settings).unwrap();
    let (u0, s0, vp0, _) = ptr.layout();
    let n_dyn = (nodes - 1) * 2;
    let mut st = ptr.iterate();
    let zbar: Vec<f64> = (0..vp0)
        .map(|i| if i >= s0 { 1.0 + 0.2 * (i as f64).cos() } else { (0.7 * i as f64).sin() })
        .collect();
    (st.xb, st.ub, st.sb) = (zbar[..u0].to_vec(), zbar[u0..s0].to_vec(), zbar[s0..].to_vec());
    ptr.linearize(&zbar, &mut st.dbar).unwrap();
    ptr.linearize_constraints(&mut st);
    let dir: Vec<f64> = (0..ptr.n_vars)
        .map(|i| if i < vp0 { 0.1 * (1.3 * i as f64 + 0.4).cos() } else { 0.0 })
        .collect();
    // The largest shift over the dynamics, nodal and peak rows for the step `t·dir`.
    let mut shifts = |t: f64| -> [f64; 3] {
        let z: Vec<f64> = dir.iter().map(|d| t * d).collect();
        for i in 0..vp0 {
            st.zc[i] = zbar[i] + z[i];
        }
        let prices = (&st.lam_vc[..], &st.lam_vb[..]);
        ptr.evaluate(&st.zc, &mut st.dcand, &mut st.ev, prices).unwrap();
        assert!(ptr.corrected_rhs(&mut st, &z));
        let shift = |r: usize| (st.soc_rhs()[r] - st.b[r]).abs();
        [
            (0..n_dyn).map(shift).fold(0.0, f64::max),
            ptr.nodal_rows.iter().map(|nr| shift(nr.row)).fold(0.0, f64::max),
            ptr.peaks.iter().map(|p| shift(p.row)).fold(0.0, f64::max),
        ]
    };
    let (big, small) = (shifts(1.0), shifts(0.5));
    assert!(!ptr.peaks.is_empty(), "peak rows");
    assert_eq!(ptr.nodal_rows.len(), 2 + 2, "the inequality on two nodes, the cone's g rows");
    for (kind, (b, s)) in ["dynamics", "nodal", "peak"].iter().zip(big.iter().zip(&small)) {
        assert!(*b > 1e-6, "{kind} rows: a shift worth checking ({b:e})");
        let ratio = b / s;
        assert!((3.0..5.5).contains(&ratio), "{kind} rows: shift ratio {ratio} (want ≈ 4)");
    }
}

/// A double integrator over 4 nodes with the interval constraint
/// `v² + 0.3·sin p + p·v ≤ 0.25` held at every grid point, `|v| ≤ v_max` (also at every grid
/// point with `velocity_rows`), the exact curvature on and `substeps` RK4 steps per segment.
fn curved_interval_problem(v_max: f64, velocity_rows: bool, substeps: usize) -> super::Ptr {
    let g = |p: &Expr, v: &Expr| &(&(v * v) + &(&p.sin() * 0.3)) + &(&(p * v) - 0.25);
    let bounds = if velocity_rows { vec![1] } else { vec![] };
    let mut ocp = double_integrator(4, v_max, [None, None], g, bounds);
    ocp.interval_constraints[0].sampling = crate::Sampling::GridPoints;
    ocp.interval_bounds_sampling = crate::Sampling::GridPoints;
    let mut settings = super::PtrSettings { exact_hessian: true, ..super::PtrSettings::default() };
    settings.discretization.substeps = substeps;
    super::Ptr::new(ocp, settings).unwrap()
}

/// The interval constraints' curvature is `Σ y·Gᵀ∇²g G` over their peak rows: along a
/// direction that leaves the dilations alone (the flow is then linear in the step, so the
/// rows' `∇g·∂²x/∂z²` the curvature leaves out vanishes), `Σ_e H_e·s` equals the
/// directional derivative of `Aᵀy` over the peak rows — central differences of the
/// subproblem's own coefficients — in every state and control column. A row at every grid
/// point, the velocity rising through each segment (no row refined between points).
#[test]
fn peak_curvature_is_the_rows_second_derivative_in_the_states() {
    use super::Ptr;
    let mut ptr = curved_interval_problem(10.0, false, 4);
    let (u0, s0, vp0, _) = ptr.layout();
    // p, v rising; accelerations positive; dilations near 1.
    let z: Vec<f64> = (0..vp0)
        .map(|i| match i {
            i if i < u0 => 0.3 * (i / 2) as f64 + if i % 2 == 1 { 0.2 } else { 0.0 },
            i if i < s0 => 0.5 + 0.1 * (i as f64).sin(),
            i => 1.0 + 0.1 * (i as f64).cos(),
        })
        .collect();
    let dir: Vec<f64> =
        (0..vp0).map(|i| if i < s0 { (1.3 * i as f64 + 0.4).cos() } else { 0.0 }).collect();
    let coefficients = |ptr: &mut Ptr, z: &[f64]| {
        let mut st = ptr.iterate();
        ptr.linearize(z, &mut st.dbar).unwrap();
        ptr.fill_peaks(&st.dbar, &mut st.ev, super::GridAt::Other);
        let stencils = st.ev.stencils.clone();
        let peak_vals = st.ev.peak_vals.clone();
        super::fill_values(&ptr.sources, &st.dbar, &st.ev, &peak_vals, &mut st.nz);
        (st.nz, stencils)
    };
    let h = 1e-5;
    let shifted =
        |sign: f64| -> Vec<f64> { z.iter().zip(&dir).map(|(z, d)| z + sign * h * d).collect() };
    let ((np, sp), (nm, sm)) =
        (coefficients(&mut ptr, &shifted(1.0)), coefficients(&mut ptr, &shifted(-1.0)));
    let mut st = ptr.iterate();
    (st.xb, st.ub, st.sb) = (z[..u0].to_vec(), z[u0..s0].to_vec(), z[s0..vp0].to_vec());
    ptr.linearize(&z, &mut st.dbar).unwrap();
    ptr.linearize_constraints(&mut st);
    // The rows' weights are the same at the three points (so their own change is not in the
    // differences).
    assert!(st.ev.stencils == sp && st.ev.stencils == sm);
    st.duals.fill(0.0);
    for (i, p) in ptr.peaks.iter().enumerate() {
        st.duals[p.row] = 0.5 + (1.7 * i as f64).sin().abs();
    }
    ptr.exact_curvature(&mut st);
    let mut model = vec![0.0; vp0];
    for (el, hb) in ptr.elements.iter().zip(&st.curv.exact) {
        let d = el.cols.len();
        for (a, &ca) in el.cols.iter().enumerate() {
            model[ca] += (0..d).map(|b| hb[a * d + b] * dir[el.cols[b]]).sum::<f64>();
        }
    }
    let peak_row: Vec<bool> = {
        let mut r = vec![false; ptr.b.len()];
        ptr.peaks.iter().for_each(|p| r[p.row] = true);
        r
    };
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for (c, m) in model.iter().enumerate().take(s0) {
        let fd: f64 = (ptr.a_colptr[c]..ptr.a_colptr[c + 1])
            .filter(|&q| peak_row[ptr.a_rowval[q]])
            .map(|q| st.duals[ptr.a_rowval[q]] * (np[q] - nm[q]) / (2.0 * h))
            .sum();
        worst = worst.max((m - fd).abs());
        scale = scale.max(fd.abs());
    }
    assert!(scale > 0.1, "a curvature worth checking: {scale}");
    assert!(worst <= 1e-5 * scale, "H·s off by {worst:e} (scale {scale:e})");
}

/// The 3-node double integrator of the grid-point row tests (velocity limit 1, rows at every
/// grid point), discretized at `z = [x (6) | u (3) | s (3)]`.
fn grid_point_double_integrator(z: &[f64; 12]) -> (super::Ptr, crate::Discretization) {
    use super::{Ptr, PtrSettings};
    let mut ocp = double_integrator(3, 1.0, [None, None], |_, v| v - 10.0, vec![1]);
    ocp.interval_bounds_sampling = crate::Sampling::GridPoints;
    let ptr = Ptr::new(ocp, PtrSettings::default()).unwrap();
    let mut ws = ptr.ocp.dynamics.workspace();
    let mut d = ptr.output();
    let settings = crate::DiscretizationSettings::default();
    ptr.ocp.dynamics.discretize(&z[..6], &z[6..9], &z[9..], &settings, &mut ws, &mut d).unwrap();
    (ptr, d)
}

/// With a row at every grid point, the half step just before an interior node is its
/// segment's own (the node's row on the next segment reaches only into that one): a velocity
/// whose only excess is the vertex of its parabola there is seen.
#[test]
fn grid_point_rows_see_a_peak_just_before_an_interior_node() {
    use super::GridAt;
    // Segment 0 lasts h = s·Δτ = 1 s with a from 1 to −0.02: v peaks at t* = 1/1.02, in the
    // last half step (0.95, 1), at v0 + t* − 1.02·t*²/2; the grid points, the node included,
    // stay below the limit.
    let (a0, a1, h) = (1.0, -0.02, 1.0);
    let t_star = a0 * h / (a0 - a1);
    let v = |v0: f64, t: f64| v0 + a0 * t + (a1 - a0) * t * t / (2.0 * h);
    let v0 = 1.0 + 1e-4 - v(0.0, t_star);
    assert!(t_star > 0.95 && v(v0, 1.0) < 1.0 && v(v0, 0.9) < 1.0);
    let (ptr, d) =
        grid_point_double_integrator(&[0.0, v0, 0.0, 0.0, 0.0, 0.0, a0, a1, 0.0, 2.0, 2.0, 2.0]);
    let mut ev = ptr.iterate().ev;
    let weights = vec![1.0; ptr.buffers.len() + ptr.peaks.len()];
    let (_, worst) = ptr.eval_peaks(&d, &mut ev, &weights, GridAt::Other);
    assert!((worst - 1e-4).abs() < 1e-9, "largest excess {worst}, the velocity's is 1e-4");
}

/// With a row at every grid point, the rows of one bound on one segment share a buffer, and
/// the merit prices each buffer's largest violation (as the subproblem's `λ·ν` does), not
/// the sum over its rows.
#[test]
fn grid_point_rows_share_their_segments_buffer_and_price_its_largest_violation() {
    use super::GridAt;
    // v = 0.5 + t on segment 0 (1 s): over the limit 1 at several grid points, by 0.5 at
    // its end; on segment 1 a falls from 1 to −1, v = 1.5 + t − t², 0.75 over at t = 0.5.
    let (ptr, d) = grid_point_double_integrator(&[
        0.0, 0.5, 0.0, 1.5, 0.0, 0.5, 1.0, 1.0, -1.0, 2.0, 2.0, 2.0,
    ]);
    let nb = ptr.buffers.len();
    // Two segments, two sides of the velocity bound: four buffers, each shared by the rows
    // of every grid point of its segment (and one per segment of the interval constraint's
    // output).
    assert_eq!(ptr.peak_buffers(), 6);
    for p in &ptr.peaks {
        let twin = |q: &&super::PeakRow| q.seg == p.seg && q.sign == p.sign && q.of == p.of;
        assert!(ptr.peaks.iter().filter(twin).all(|q| q.buffer == p.buffer));
        assert!(ptr.peaks.iter().filter(|q| !twin(q)).all(|q| q.buffer != p.buffer));
        let col = ptr.vb0 + nb + p.buffer;
        let entries = ptr.a_colptr[col]..ptr.a_colptr[col + 1];
        assert!(ptr.a_rowval[entries].contains(&p.row), "row {} lacks its buffer", p.row);
    }
    let mut ev = ptr.iterate().ev;
    let weights: Vec<f64> = (0..nb + ptr.peaks.len()).map(|i| 1.0 + i as f64).collect();
    let (priced, worst) = ptr.eval_peaks(&d, &mut ev, &weights, GridAt::Other);
    let mut largest = [0.0f64; 6];
    let mut summed = 0.0;
    for (i, p) in ptr.peaks.iter().enumerate() {
        largest[p.buffer] = largest[p.buffer].max(ev.violation[nb + i]);
        summed += weights[nb + p.buffer] * ev.violation[nb + i];
    }
    let expected: f64 = largest.iter().enumerate().map(|(b, v)| weights[nb + b] * v).sum();
    assert!((worst - 0.75).abs() < 1e-9, "largest excess {worst}");
    assert!((priced - expected).abs() < 1e-12, "{priced} against {expected}");
    assert!(summed > 2.0 * expected, "several rows of a buffer over: {summed} vs {expected}");
}

/// The inexact solves' tolerance: loosest for the first subproblem, then `inexact` times
/// the last predicted decrease (relative to the cost where the cost exceeds 1), never
/// tighter than the interior point's own tolerance; 0 turns it off, and a record without a
/// prediction asks for the tight tolerance.
#[test]
fn inexact_solves_follow_the_last_predicted_decrease() {
    use super::{Iteration, SubproblemSettings};
    let set = SubproblemSettings::default();
    let (tight, loosest) = (set.interior_point.tolerance, set.loosest_tolerance);
    assert_eq!(set.inexact_tolerance(None), loosest);
    let record = |cost: f64, predicted: f64| Iteration {
        cost,
        predicted,
        ..Iteration::pending(1, 1.0, 1.0, false)
    };
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b;
    assert_eq!(set.inexact_tolerance(Some(&record(1.2, 0.3))), loosest);
    assert!(close(set.inexact_tolerance(Some(&record(0.5, 2e-3))), 1e-3 * 2e-3));
    assert!(close(set.inexact_tolerance(Some(&record(4.0, 2e-3))), 1e-3 * 2e-3 / 4.0));
    assert_eq!(set.inexact_tolerance(Some(&record(1.2, 1e-9))), tight);
    assert_eq!(set.inexact_tolerance(Some(&record(1.2, f64::NAN))), tight);
    let exact = SubproblemSettings { inexact: 0.0, ..SubproblemSettings::default() };
    assert_eq!(exact.inexact_tolerance(None), tight);
    assert_eq!(exact.inexact_tolerance(Some(&record(1.2, 0.3))), tight);
    let mut bad = crate::PtrSettings::default();
    bad.subproblem.inexact = -1.0;
    assert_eq!(bad.validate().unwrap_err().field, "subproblem.inexact");
}

/// The peak rows' curvature, the vertex's included (`peak_envelope.rs`), is the second
/// derivative of the rows' peak values: along a direction that leaves the dilations alone
/// (the flow is then linear in the step), `sᵀ(Σ_e H_e)s` equals `Σ y·(ĝ(z + hs) − 2ĝ(z) +
/// ĝ(z − hs))/h²` over the rows, each peak recomputed with its vertex free to move. The
/// accelerations change sign inside the segments, so the velocity (bounded at every grid
/// point) and the interval constraint peak between grid points; without the vertex's term
/// the curvature misses a good share of it.
#[test]
fn peak_envelope_curvature_is_the_peaks_second_derivative() {
    use super::GridAt;
    let nodes = 4;
    let mut ptr = curved_interval_problem(0.6, true, 6);
    let (u0, s0, vp0, _) = ptr.layout();
    // p, v from the dynamics' own start; accelerations alternating in sign at the nodes.
    let z: Vec<f64> = (0..vp0)
        .map(|i| match i {
            i if i < u0 => 0.0,
            i if i < s0 => {
                if (i - u0) % 2 == 0 {
                    0.9
                } else {
                    -0.8
                }
            }
            _ => 1.0,
        })
        .collect();
    let mut st = ptr.iterate();
    (st.xb, st.ub, st.sb) = (z[..u0].to_vec(), z[u0..s0].to_vec(), z[s0..vp0].to_vec());
    ptr.linearize(&z, &mut st.dbar).unwrap();
    // The states at the nodes where the accelerations take them (no defects).
    let n = 2;
    for k in 0..nodes - 1 {
        let next = st.dbar.x_prop[k * n..(k + 1) * n].to_vec();
        st.xb[(k + 1) * n..(k + 2) * n].copy_from_slice(&next);
        let z: Vec<f64> = [&st.xb[..], &st.ub[..], &st.sb[..]].concat();
        ptr.linearize(&z, &mut st.dbar).unwrap();
    }
    let z: Vec<f64> = [&st.xb[..], &st.ub[..], &st.sb[..]].concat();
    ptr.linearize_constraints(&mut st);
    let pts = st.dbar.grid_points;
    let stride = ptr.ocp.dynamics.grid_stride();
    let interior = ptr
        .peaks
        .iter()
        .filter(|p| {
            let at = |j: usize| match p.of {
                super::PeakOf::State(r) => p.sign * st.dbar.grid[(p.seg * pts + j) * stride + r],
                super::PeakOf::Function { .. } => 0.0,
            };
            matches!(p.of, super::PeakOf::State(_))
                && super::evaluate::vertex(pts, p.at, &at).interior
        })
        .count();
    assert!(interior >= 2, "rows whose vertex lies inside their cell: {interior}");
    let dir: Vec<f64> =
        (0..vp0).map(|i| if i < s0 { 0.3 * (1.3 * i as f64 + 0.4).cos() } else { 0.0 }).collect();
    let elements = ptr.elements.clone();
    let quadratic = |curv: &[Vec<f64>]| -> f64 {
        elements
            .iter()
            .zip(curv)
            .map(|(el, hb)| {
                let d = el.cols.len();
                (0..d)
                    .flat_map(|a| (0..d).map(move |b| (a, b)))
                    .map(|(a, b)| dir[el.cols[a]] * hb[a * d + b] * dir[el.cols[b]])
                    .sum::<f64>()
            })
            .sum()
    };
    // Duals on the velocity bound's rows only (linear in the states: the vertex's motion is
    // all their curvature), then on every row.
    for states_only in [true, false] {
        st.duals.fill(0.0);
        for (i, p) in ptr.peaks.iter().enumerate() {
            if !states_only || matches!(p.of, super::PeakOf::State(_)) {
                st.duals[p.row] = 0.5 + (1.7 * i as f64).sin().abs();
            }
        }
        for h in &mut st.curv.exact {
            h.fill(0.0);
        }
        ptr.peak_curvature(&mut st);
        let without = quadratic(&st.curv.exact);
        ptr.exact_curvature(&mut st);
        let model = quadratic(&st.curv.exact);
        let duals = st.duals.clone();
        let mut peaks = |t: f64| -> f64 {
            let zt: Vec<f64> = z.iter().zip(&dir).map(|(z, d)| z + t * d).collect();
            let mut d = ptr.output();
            ptr.linearize(&zt, &mut d).unwrap();
            let weights = vec![0.0; ptr.buffers.len() + ptr.peaks.len()];
            ptr.eval_peaks(&d, &mut st.ev, &weights, GridAt::Other);
            ptr.peaks.iter().map(|p| duals[p.row] * ptr.peak(&d, &st.ev, p).0).sum()
        };
        let h = 1e-4;
        let fd = (peaks(h) - 2.0 * peaks(0.0) + peaks(-h)) / (h * h);
        assert!(fd.abs() > 1e-2, "a curvature worth checking: {fd}");
        assert!((model - fd).abs() <= 1e-4 * fd.abs(), "sᵀHs {model} against {fd}");
        if states_only {
            assert_eq!(without, 0.0, "no curvature but the vertex's in a bound on a state");
        }
    }
}

/// The local-infeasibility test on made-up histories: a violation pinned for the window while
/// the final time stands still is stuck; one that shrinks, moves by factors, is traded for
/// time, or drops within tolerance somewhere in the window is not; a refused step carries the
/// last accepted reference; window 0 turns the test off.
#[test]
fn a_violation_pinned_for_the_window_is_local_infeasibility() {
    use super::step::locally_infeasible;
    use super::{Iteration, PtrSettings};
    let set = PtrSettings::default();
    let w = set.infeasible_window;
    let record = |violation: f64, final_time: f64, accepted: bool| {
        let mut r = Iteration::pending(1, final_time, 1.0, false);
        (r.accepted, r.max_violation, r.max_defect) = (accepted, violation, 0.0);
        r
    };
    let pinned: Vec<Iteration> = (0..w).map(|_| record(3.8e-4, 1.2, true)).collect();
    assert!(locally_infeasible(&pinned, &set));
    assert!(!locally_infeasible(&pinned[1..], &set), "fewer records than the window");
    let shrinking: Vec<Iteration> =
        (0..w).map(|k| record(3.8e-4 * 0.95f64.powi(k as i32), 1.2, true)).collect();
    assert!(!locally_infeasible(&shrinking, &set));
    let trading: Vec<Iteration> =
        (0..w).map(|k| record(3.8e-4, 1.2 - 1e-3 * k as f64, true)).collect();
    assert!(!locally_infeasible(&trading, &set));
    let mut spiky = pinned.clone();
    spiky[3] = record(1e-2, 1.2, true);
    assert!(!locally_infeasible(&spiky, &set), "moves by factors");
    let mut feasible = pinned.clone();
    feasible[w - 1] = record(1e-7, 1.2, true);
    assert!(!locally_infeasible(&feasible, &set));
    // Refused candidates (their own violations far off) leave the reference pinned.
    let mut refused = pinned.clone();
    for r in refused.iter_mut().skip(1).step_by(2) {
        *r = record(5.0, 0.9, false);
    }
    assert!(locally_infeasible(&refused, &set));
    let off = PtrSettings { infeasible_window: 0, ..set };
    assert!(!locally_infeasible(&pinned, &off));
}

/// A solve's prices are named by the rows they price — each nodal constraint's output at
/// its node (a ball's norm as one), each bound between the nodes on its segment — one per
/// buffer in buffer order; a solve started from given prices starts at them (never below
/// the settings', bad entries ignored, the trust region clamped), and the same problem
/// started from its own final prices buys no more than it must: it converges in fewer
/// iterations than from the settings' prices.
#[test]
fn prices_are_named_by_their_rows_and_start_the_next_solve() {
    use super::{NodalKind, PeakBound, PricedRow, Ptr, PtrSettings};
    // v² + 0.1·sin(p) ≤ 0.25 between the nodes, |v| ≤ 0.45 there too, 0 → 1 m at rest;
    // p ≤ 0.8 and v ≤ 0.4 at nodes 1 and 2, (p, v) within 0.6 of (0.5, 0) at node 3.
    let nodes = 6;
    let g = |p: &Expr, v: &Expr| &(v * v) + &(&p.sin() * 0.1) - 0.25;
    let mut ocp = double_integrator(nodes, 0.45, [Some(1.0), Some(0.0)], g, vec![1]);
    let (p, v, a) = (Expr::variable("p", 1), Expr::variable("v", 1), Expr::variable("a", 1));
    let groups: &[&[Expr]] = &[&[p.clone(), v.clone()], &[a]];
    let nodal = |name: &str, f: Expr, nodes: Vec<usize>, kind| {
        nodal_constraint(name, f, groups, nodes, kind)
    };
    let ineq = Expr::concat(&[&p - 0.8, &v - 0.4]);
    let ball = Expr::concat(&[&p - 0.5, v.clone()]);
    ocp.nodal = vec![
        nodal("ineq", ineq, vec![1, 2], NodalKind::Inequality),
        nodal("ball", ball, vec![3], NodalKind::Ball { radius: 0.6 }),
    ];
    let settings = PtrSettings { max_iterations: 120, ..PtrSettings::default() };
    let mut ptr = Ptr::new(ocp, settings.clone()).unwrap();
    let rows = ptr.priced_rows();
    assert_eq!(rows.len(), ptr.buffers.len() + ptr.peak_buffers());
    let nodal = |constraint, node, output| PricedRow::Nodal { constraint, node, output };
    let expected_nodal =
        [nodal(0, 1, Some(0)), nodal(0, 1, Some(1)), nodal(0, 2, Some(0)), nodal(0, 2, Some(1))];
    assert_eq!(&rows[..4], &expected_nodal);
    assert_eq!(rows[4], nodal(1, 3, None));
    let between = |bound, segment| PricedRow::BetweenNodes { bound, segment };
    for segment in 0..nodes - 1 {
        for upper in [false, true] {
            let velocity = between(PeakBound::State { row: 1, upper }, segment);
            assert_eq!(rows.iter().filter(|r| **r == velocity).count(), 1, "{velocity:?}");
        }
        let g = between(PeakBound::Function { constraint: 0, output: 0 }, segment);
        assert_eq!(rows.iter().filter(|r| **r == g).count(), 1, "{g:?}");
    }
    assert!(ptr.prices().is_none(), "no prices before a solve");

    let x: Vec<f64> = (0..nodes).flat_map(|k| [k as f64 / (nodes - 1) as f64, 0.0]).collect();
    let (u, s) = (vec![0.0; nodes], vec![3.0; nodes]);
    let first = ptr.solve(&x, &u, &s).unwrap();
    assert_eq!(first.status, super::PtrStatus::Converged, "{:?}", first.max_violation);
    let prices = first.prices.clone();
    let named: Vec<PricedRow> = prices.rows.iter().map(|r| r.0).collect();
    assert_eq!(named, rows);
    assert!(prices.rows.iter().all(|r| r.1 >= settings.lam_vb));
    assert!(prices.rows.iter().any(|r| r.1 > settings.lam_vb), "no price was raised");
    assert_eq!(prices.state_rows.len(), 2);

    // Started from given prices: where given, at them (never below the settings'); a NaN,
    // a negative price and a state-row list of the wrong length are ignored.
    let given = |row: PricedRow| match row {
        PricedRow::Nodal { node: 1, .. } => Some(7.0),
        PricedRow::Nodal { node: 2, .. } => Some(f64::NAN),
        PricedRow::Nodal { .. } => Some(-1.0),
        PricedRow::BetweenNodes { segment, .. } => Some(0.01 + segment as f64),
    };
    ptr.set_starting_prices(&[5.0], given, Some(1e9));
    ptr.start(&x, &u, &s).unwrap();
    let started = ptr.prices().unwrap();
    for (row, price) in &started.rows {
        let want = match given(*row) {
            Some(p) if p.is_finite() && p > 0.0 => p.max(settings.lam_vb),
            _ => settings.lam_vb,
        };
        assert_eq!(*price, want, "{row:?}");
    }
    assert!(started.state_rows.iter().all(|&p| p == settings.lam_vc));
    assert_eq!(started.trust_region, settings.lam_tr_max);

    // From its own final prices (and a trust region as loose as the solve ended with), the
    // same problem converges again in fewer iterations.
    let own = |row: PricedRow| prices.rows.iter().find(|r| r.0 == row).map(|r| r.1);
    ptr.set_starting_prices(&prices.state_rows, own, Some(prices.trust_region));
    let again = ptr.solve(&x, &u, &s).unwrap();
    assert_eq!(again.status, super::PtrStatus::Converged);
    assert!(
        again.history.len() < first.history.len(),
        "{} iterations from its own prices, {} from the settings'",
        again.history.len(),
        first.history.len()
    );
}
