//! The discretization's matrices are the exact derivatives of its propagation map, and the
//! propagation is exact where RK4 must be.

use armature_scvx::{DiscretizationSettings, Dynamics};
use armature_symbolic::Expr;

/// A pendulum-on-a-cart-like nonlinear system: 3 states, one FOH and one ZOH control.
fn nonlinear() -> Dynamics {
    let x = Expr::variable("x", 3);
    let u = Expr::variable("u", 2);
    let rhs = [
        x.at(1),
        -(x.at(0).sin()) * 9.81 + u.at(0) * x.at(2).cos() - x.at(1) * 0.1,
        u.at(1) * 2.0 + x.at(0) * x.at(1),
    ];
    let f = Expr::concat(&rhs);
    Dynamics::new(&[x], &[u], &[f], &[true, false]).unwrap()
}

/// [`nonlinear`] with a term quadratic in `u_0` and one in `u_0·u_1`, and `u_0` (first-order
/// hold) time-scaled: the solver's variable is `w_0 = s·u_0`, so the map is
/// `s·f(x, w_0/s, u_1)` — its curvature in `(w_0, s)` exercises every term of the
/// transformed `G`, plain and scaled entries mixed.
fn nonlinear_scaled() -> Dynamics {
    let x = Expr::variable("x", 3);
    let u = Expr::variable("u", 2);
    let rhs = [
        x.at(1),
        -(x.at(0).sin()) * 9.81 + u.at(0) * x.at(2).cos() - x.at(1) * 0.1 + u.at(0) * u.at(0) * 0.2,
        u.at(1) * 2.0 + x.at(0) * x.at(1) + u.at(0) * u.at(1) * 0.5,
    ];
    let f = Expr::concat(&rhs);
    Dynamics::new(&[x], &[u], &[f], &[true, false]).unwrap().time_scaled(&[true, false]).unwrap()
}

fn propagate(d: &Dynamics, x: &[f64], u: &[f64], s: &[f64]) -> Vec<f64> {
    let mut ws = d.workspace();
    let mut out = d.output(s.len());
    d.discretize(x, u, s, &DiscretizationSettings::default(), &mut ws, &mut out).unwrap();
    out.x_prop
}

#[test]
fn matrices_are_derivatives_of_the_propagation_map() {
    matrices_are_derivatives_of(nonlinear());
}

/// With a time-scaled control the dilation's column carries `f − Σ ∂f/∂u_i·u_i` and the
/// control's columns lose their factor `s`: still the map's exact derivatives.
#[test]
fn matrices_are_derivatives_of_the_map_with_a_time_scaled_control() {
    matrices_are_derivatives_of(nonlinear_scaled());
}

/// A time-scaled control enters the dynamics as `w/s`: the propagation from `w = s·u` is the
/// plain control's from `u`, segment by segment.
#[test]
fn a_time_scaled_control_propagates_as_its_physical_value() {
    let (plain, scaled) = (nonlinear(), nonlinear().time_scaled(&[true, false]).unwrap());
    let (n, mu, nodes) = (3, 2, 4);
    let x: Vec<f64> = (0..nodes * n).map(|i| (i as f64 * 0.7).sin()).collect();
    let s = [1.5, 1.5, 1.5, 1.5];
    let u: Vec<f64> = (0..nodes * mu).map(|i| (i as f64 * 1.3).cos()).collect();
    let mut w = u.clone();
    scaled.holds().to_solver(&mut w, &s);
    assert_eq!(w[0], 1.5 * u[0]);
    assert_eq!(w[1], u[1]);
    let (a, b) = (propagate(&plain, &x, &u, &s), propagate(&scaled, &x, &w, &s));
    for (a, b) in a.iter().zip(&b) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
    assert!(nonlinear().time_scaled(&[true]).is_err(), "a mask of the wrong length");
}

fn matrices_are_derivatives_of(d: Dynamics) {
    let (n, mu) = (3, 2);
    let m = mu + 1;
    let nodes = 4;
    let x: Vec<f64> = (0..nodes * n).map(|i| (i as f64 * 0.7).sin()).collect();
    let u: Vec<f64> = (0..nodes * mu).map(|i| (i as f64 * 1.3).cos()).collect();
    let s: Vec<f64> = vec![1.5, 1.2, 2.0, 2.0];
    let mut ws = d.workspace();
    let mut out = d.output(nodes);
    d.discretize(&x, &u, &s, &DiscretizationSettings::default(), &mut ws, &mut out).unwrap();
    let h = 1e-6;
    for seg in 0..nodes - 1 {
        // ∂x_prop/∂x_k = A_k.
        for j in 0..n {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[seg * n + j] += h;
            xm[seg * n + j] -= h;
            let (pp, pm) = (propagate(&d, &xp, &u, &s), propagate(&d, &xm, &u, &s));
            for r in 0..n {
                let fd = (pp[seg * n + r] - pm[seg * n + r]) / (2.0 * h);
                let a = out.a[seg * n * n + r * n + j];
                assert!((a - fd).abs() < 1e-7, "A[{seg}][{r},{j}] = {a} vs FD {fd}");
            }
        }
        // ∂x_prop/∂u_k = B⁻ (control columns), ∂x_prop/∂u_{k+1} = B⁺.
        for i in 0..mu {
            for (node, mat, name) in [(seg, &out.b_minus, "B-"), (seg + 1, &out.b_plus, "B+")] {
                let (mut up, mut um) = (u.clone(), u.clone());
                up[node * mu + i] += h;
                um[node * mu + i] -= h;
                let (pp, pm) = (propagate(&d, &x, &up, &s), propagate(&d, &x, &um, &s));
                for r in 0..n {
                    let fd = (pp[seg * n + r] - pm[seg * n + r]) / (2.0 * h);
                    let b = mat[seg * n * m + r * m + i];
                    assert!((b - fd).abs() < 1e-7, "{name}[{seg}][{r},{i}] = {b} vs FD {fd}");
                }
            }
        }
        // ∂x_prop/∂s_k is the last column of B⁻; B⁺ has none (s is zero-order hold).
        let (mut sp, mut sm) = (s.clone(), s.clone());
        sp[seg] += h;
        sm[seg] -= h;
        let (pp, pm) = (propagate(&d, &x, &u, &sp), propagate(&d, &x, &u, &sm));
        for r in 0..n {
            let fd = (pp[seg * n + r] - pm[seg * n + r]) / (2.0 * h);
            assert!((out.b_minus[seg * n * m + r * m + mu] - fd).abs() < 1e-7);
            assert_eq!(out.b_plus[seg * n * m + r * m + mu], 0.0);
        }
        // The ZOH control has no B⁺ column.
        for r in 0..n {
            assert_eq!(out.b_plus[seg * n * m + r * m + 1], 0.0);
        }
    }
    for seg in 0..nodes - 1 {
        for r in 0..n {
            assert!(
                (out.defect[seg * n + r] - (x[(seg + 1) * n + r] - out.x_prop[seg * n + r])).abs()
                    < 1e-15
            );
        }
    }
}

/// Double integrator with FOH acceleration: the state is a cubic in τ, which RK4 integrates
/// exactly, so x_prop equals the closed form to round-off (and one substep suffices).
/// `p' = v, v' = a` with a first-order-hold acceleration, on 3 nodes: its segment 0 lasts
/// T = s·Δτ = 1 s with the acceleration going linearly from 1 to −2.
fn double_integrator() -> (Dynamics, [f64; 6], [f64; 3], [f64; 3]) {
    let p = Expr::variable("p", 1);
    let v = Expr::variable("v", 1);
    let a = Expr::variable("a", 1);
    let d = Dynamics::new(&[p, v.clone()], &[a.clone()], &[v, a], &[true]).unwrap();
    (d, [0.3, -0.2, 0.0, 0.0, 0.0, 0.0], [1.0, -2.0, 0.5], [2.0, 0.5, 0.5])
}

#[test]
fn double_integrator_is_exact() {
    let (d, x, u, s) = double_integrator();
    let nodes = 3;
    for substeps in [1, 4] {
        let mut ws = d.workspace();
        let mut out = d.output(nodes);
        d.discretize(
            &x,
            &u,
            &s,
            &{
                let mut s = DiscretizationSettings::default();
                s.substeps = substeps;
                s
            },
            &mut ws,
            &mut out,
        )
        .unwrap();
        // Segment 0: duration T = s·Δτ = 1, acceleration linear from 1 to −2.
        let (t, a0, a1) = (2.0 * 0.5, 1.0, -2.0);
        let v_end = -0.2 + a0 * t + (a1 - a0) * t / 2.0;
        let p_end = 0.3 - 0.2 * t + a0 * t * t / 2.0 + (a1 - a0) * t * t / 6.0;
        assert!((out.x_prop[0] - p_end).abs() < 1e-14, "{}", out.x_prop[0]);
        assert!((out.x_prop[1] - v_end).abs() < 1e-14);
        // A = [[1, T], [0, 1]].
        assert!(
            (out.a[0] - 1.0).abs() < 1e-14
                && (out.a[1] - t).abs() < 1e-14
                && out.a[2].abs() < 1e-14
        );
    }
}

#[test]
fn size_errors_are_reported() {
    let d = nonlinear();
    let mut ws = d.workspace();
    let mut out = d.output(3);
    let err = d.discretize(
        &[0.0; 8],
        &[0.0; 6],
        &[1.0; 3],
        &DiscretizationSettings::default(),
        &mut ws,
        &mut out,
    );
    assert!(err.unwrap_err().to_string().contains("x of 9 (got 8)"));
    let x = Expr::variable("x", 2);
    let u = Expr::variable("u", 1);
    assert!(
        Dynamics::new(&[x.clone()], &[u.clone()], &[x.at(0)], &[true]).is_err(),
        "1 entry for 2 states"
    );
    assert!(
        Dynamics::new(&[x.clone()], &[u.clone()], &[x.clone()], &[true, false]).is_err(),
        "mask length"
    );
}

/// A system with structural zeros: a double integrator beside a decoupled scalar
/// `z' = z·w` (the integrator never sees `z` or `w`, `z` never sees the integrator).
fn block_diagonal() -> Dynamics {
    let p = Expr::variable("p", 1);
    let v = Expr::variable("v", 1);
    let z = Expr::variable("z", 1);
    let a = Expr::variable("a", 1);
    let w = Expr::variable("w", 1);
    let rhs = [v.clone(), a.clone(), &z * &w];
    Dynamics::new(&[p, v, z], &[a, w], &rhs, &[true, true]).unwrap()
}

#[test]
fn transition_pattern_is_the_reachability_of_the_jacobian() {
    let d = block_diagonal();
    let tp = d.transition_pattern();
    assert_eq!((tp.nrows(), tp.ncols()), (3, 3 + 2 + 1));
    // Columns [p v z | a w | s]: p is reached from p, v and a; v from v and a; z from z, w.
    let expected: &[(usize, usize)] =
        &[(0, 0), (0, 1), (0, 3), (0, 5), (1, 1), (1, 3), (1, 5), (2, 2), (2, 4), (2, 5)];
    let got: Vec<(usize, usize)> = {
        let mut e: Vec<_> = tp.entries().collect();
        e.sort();
        e
    };
    assert_eq!(got, expected);
    assert_eq!(d.state_name(2), Some("z"));
    assert_eq!(d.state_name(3), None);
}

#[test]
fn discretized_entries_outside_the_pattern_are_exactly_zero() {
    for d in [block_diagonal(), nonlinear()] {
        let (n, mu) = (d.n_x(), d.n_u());
        let m = mu + 1;
        let nodes = 5;
        let x: Vec<f64> = (0..nodes * n).map(|i| (i as f64 * 0.37).sin()).collect();
        let u: Vec<f64> = (0..nodes * mu).map(|i| (i as f64 * 0.91).cos()).collect();
        let s = vec![1.3; nodes];
        let mut ws = d.workspace();
        let mut out = d.output(nodes);
        d.discretize(&x, &u, &s, &DiscretizationSettings::default(), &mut ws, &mut out).unwrap();
        let tp = d.transition_pattern();
        let mut nonzero_outside = 0;
        for k in 0..nodes - 1 {
            for r in 0..n {
                for j in 0..n {
                    if !tp.contains(r, j) && out.a[k * n * n + r * n + j] != 0.0 {
                        nonzero_outside += 1;
                    }
                }
                for c in 0..m {
                    let inside = tp.contains(r, n + c);
                    let (bm, bp) =
                        (out.b_minus[k * n * m + r * m + c], out.b_plus[k * n * m + r * m + c]);
                    if !inside && (bm != 0.0 || bp != 0.0) {
                        nonzero_outside += 1;
                    }
                }
            }
        }
        assert_eq!(nonzero_outside, 0);
    }
    // The block-diagonal system really has zeros to drop.
    assert_eq!(block_diagonal().transition_pattern().nnz(), 10);
}

#[test]
fn parallel_and_serial_discretization_agree_bitwise() {
    let d = nonlinear();
    let (n, mu) = (3, 2);
    for nodes in [2, 3, 7, 12] {
        let x: Vec<f64> = (0..nodes * n).map(|i| (i as f64 * 0.53).cos()).collect();
        let u: Vec<f64> = (0..nodes * mu).map(|i| (i as f64 * 0.29).sin()).collect();
        let s: Vec<f64> = (0..nodes).map(|k| 1.0 + 0.1 * k as f64).collect();
        let mut outs = Vec::new();
        for parallel in [false, true] {
            let settings = {
                let mut s = DiscretizationSettings::default();
                s.parallel = parallel;
                s
            };
            let mut ws = d.workspace();
            let mut out = d.output(nodes);
            d.discretize(&x, &u, &s, &settings, &mut ws, &mut out).unwrap();
            outs.push(out);
        }
        assert_eq!(outs[0], outs[1], "{nodes} nodes");
    }
}

/// `defects` (no variational equations) gives `discretize`'s propagated states and defects
/// bit for bit, with RK4 and with Dormand–Prince (whose step control looks at the state
/// only), and leaves the matrices alone.
#[test]
fn defects_alone_equal_the_full_discretization_bitwise() {
    let d = nonlinear();
    let (n, mu) = (3, 2);
    let nodes = 5;
    let x: Vec<f64> = (0..nodes * n).map(|i| (i as f64 * 0.41).sin()).collect();
    let u: Vec<f64> = (0..nodes * mu).map(|i| (i as f64 * 0.77).cos()).collect();
    let s: Vec<f64> = (0..nodes).map(|k| 1.2 + 0.3 * k as f64).collect();
    for settings in [DiscretizationSettings::default(), dp(1e-9, 1e-11)] {
        let mut ws = d.workspace();
        let mut full = d.output(nodes);
        d.discretize(&x, &u, &s, &settings, &mut ws, &mut full).unwrap();
        let mut alone = d.output(nodes);
        alone.a.fill(7.0);
        d.defects(&x, &u, &s, &settings, &mut ws, &mut alone).unwrap();
        assert_eq!(alone.x_prop, full.x_prop);
        assert_eq!(alone.defect, full.defect);
        assert!(alone.a.iter().all(|&v| v == 7.0), "matrices untouched");
    }
}

fn dp(rtol: f64, atol: f64) -> DiscretizationSettings {
    let mut s = DiscretizationSettings::default();
    s.integrator = armature_scvx::Integrator::DormandPrince { rtol, atol };
    s
}

#[test]
fn dormand_prince_agrees_with_fine_rk4_and_its_matrices_are_derivatives() {
    let d = nonlinear();
    let (n, mu) = (3, 2);
    let nodes = 4;
    let x: Vec<f64> = (0..nodes * n).map(|i| (i as f64 * 0.7).sin()).collect();
    let u: Vec<f64> = (0..nodes * mu).map(|i| (i as f64 * 1.3).cos()).collect();
    let s = vec![1.5, 1.2, 2.0, 2.0];
    let run = |settings: &DiscretizationSettings, x: &[f64]| {
        let mut ws = d.workspace();
        let mut out = d.output(nodes);
        d.discretize(x, &u, &s, settings, &mut ws, &mut out).unwrap();
        out
    };
    let fine = run(
        &{
            let mut s = DiscretizationSettings::default();
            s.substeps = 400;
            s
        },
        &x,
    );
    let adaptive = run(&dp(1e-11, 1e-13), &x);
    let close = |a: &[f64], b: &[f64], tol: f64| a.iter().zip(b).all(|(p, q)| (p - q).abs() < tol);
    assert!(close(&adaptive.x_prop, &fine.x_prop, 1e-9), "{:?} {:?}", adaptive.x_prop, fine.x_prop);
    assert!(close(&adaptive.a, &fine.a, 1e-8));
    assert!(close(&adaptive.b_minus, &fine.b_minus, 1e-8));
    assert!(close(&adaptive.b_plus, &fine.b_plus, 1e-8));
    // Central differences of the adaptive map in the state of segment 1.
    let h = 1e-6;
    for j in 0..n {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[n + j] += h;
        xm[n + j] -= h;
        let (p, m) = (run(&dp(1e-11, 1e-13), &xp), run(&dp(1e-11, 1e-13), &xm));
        for r in 0..n {
            let fd = (p.x_prop[n + r] - m.x_prop[n + r]) / (2.0 * h);
            let a = adaptive.a[n * n + r * n + j];
            assert!((fd - a).abs() < 1e-6 * (1.0 + a.abs()), "A[{r},{j}] {a} vs {fd}");
        }
    }
    // Loose tolerances take fewer, larger steps and stay close.
    let loose = run(&dp(1e-6, 1e-8), &x);
    assert!(close(&loose.x_prop, &fine.x_prop, 1e-4));
}

#[test]
fn dormand_prince_that_cannot_meet_its_tolerance_is_an_error() {
    let d = nonlinear();
    let nodes = 3;
    let x = vec![0.3; nodes * 3];
    let u = vec![0.5; nodes * 2];
    let s = vec![1.0; nodes];
    let mut ws = d.workspace();
    let mut out = d.output(nodes);
    let err = d.discretize(&x, &u, &s, &dp(1e-300, 1e-300), &mut ws, &mut out).unwrap_err();
    assert!(err.to_string().contains("cannot be met"), "{err}");
}

/// The grid of [`Dynamics::output_with_grid`]: block j of segment k holds the state and its
/// sensitivities after j of the segment's RK4 substeps. Its ends are the node and the
/// propagation; its interior sensitivities are central differences of its interior states;
/// `defects` writes the same states bitwise.
#[test]
fn grid_records_the_trajectory_and_its_sensitivities_between_nodes() {
    let d = nonlinear();
    let (n, mu) = (3, 2);
    let m = mu + 1;
    let nodes = 4;
    let substeps = 6;
    let settings = {
        let mut s = DiscretizationSettings::default();
        s.substeps = substeps;
        s
    };
    let stride = d.grid_stride();
    assert_eq!(stride, n + n * n + 2 * n * m);
    let x: Vec<f64> = (0..nodes * n).map(|i| (i as f64 * 0.7).sin()).collect();
    let u: Vec<f64> = (0..nodes * mu).map(|i| (i as f64 * 1.3).cos()).collect();
    let s: Vec<f64> = vec![1.5, 1.2, 2.0, 2.0];
    let run = |x: &[f64], u: &[f64], s: &[f64]| {
        let mut ws = d.workspace();
        let mut out = d.output_with_grid(nodes, substeps);
        d.discretize(x, u, s, &settings, &mut ws, &mut out).unwrap();
        out
    };
    let out = run(&x, &u, &s);
    let pts = substeps + 1;
    assert_eq!(out.grid_points, pts);
    assert_eq!(out.grid.len(), (nodes - 1) * pts * stride);
    let block = |o: &armature_scvx::Discretization, k: usize, j: usize| {
        o.grid[(k * pts + j) * stride..(k * pts + j + 1) * stride].to_vec()
    };
    let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * m);
    for k in 0..nodes - 1 {
        // j = 0: the node, Φ = I, B± = 0.
        let b0 = block(&out, k, 0);
        assert_eq!(&b0[..n], &x[k * n..(k + 1) * n]);
        for r in 0..n {
            for c in 0..n {
                assert_eq!(b0[phi0 + r * n + c], f64::from(u8::from(r == c)));
            }
        }
        assert!(b0[bm0..].iter().all(|&v| v == 0.0));
        // j = substeps: the propagation and the segment's matrices, bitwise.
        let last = block(&out, k, substeps);
        assert_eq!(&last[..n], &out.x_prop[k * n..(k + 1) * n]);
        assert_eq!(&last[phi0..bm0], &out.a[k * n * n..(k + 1) * n * n]);
        assert_eq!(&last[bm0..bp0], &out.b_minus[k * n * m..(k + 1) * n * m]);
        assert_eq!(&last[bp0..], &out.b_plus[k * n * m..(k + 1) * n * m]);
    }
    // Interior points: sensitivities against central differences of the grid states.
    let h = 1e-6;
    let k = 1;
    let check = |dir: &dyn Fn(f64) -> (Vec<f64>, Vec<f64>, Vec<f64>),
                 col: &dyn Fn(usize) -> usize| {
        let (xp, up, sp) = dir(h);
        let (xm, um, sm) = dir(-h);
        let (p, q) = (run(&xp, &up, &sp), run(&xm, &um, &sm));
        for j in 1..substeps {
            let (bp, bq, b) = (block(&p, k, j), block(&q, k, j), block(&out, k, j));
            for r in 0..n {
                let fd = (bp[r] - bq[r]) / (2.0 * h);
                let an = b[col(r)];
                assert!((fd - an).abs() < 1e-7 * (1.0 + an.abs()), "j {j} row {r}: {an} vs {fd}");
            }
        }
    };
    for c in 0..n {
        let dir = |e: f64| {
            let mut xx = x.clone();
            xx[k * n + c] += e;
            (xx, u.clone(), s.clone())
        };
        check(&dir, &|r| phi0 + r * n + c);
    }
    for i in 0..mu {
        for (node, base) in [(k, bm0), (k + 1, bp0)] {
            let dir = |e: f64| {
                let mut uu = u.clone();
                uu[node * mu + i] += e;
                (x.clone(), uu, s.clone())
            };
            check(&dir, &|r| base + r * m + i);
        }
    }
    let dir = |e: f64| {
        let mut ss = s.clone();
        ss[k] += e;
        (x.clone(), u.clone(), ss)
    };
    check(&dir, &|r| bm0 + r * m + mu);
    // Defects alone write the same grid states.
    let mut ws = d.workspace();
    let mut alone = d.output_with_grid(nodes, substeps);
    d.defects(&x, &u, &s, &settings, &mut ws, &mut alone).unwrap();
    for k in 0..nodes - 1 {
        for j in 0..pts {
            assert_eq!(&block(&alone, k, j)[..n], &block(&out, k, j)[..n]);
        }
    }
}

/// On the double integrator with a first-order-hold acceleration the state is a cubic in
/// time, which RK4 integrates exactly: every grid point is the closed form, with RK4 and with
/// Dormand–Prince (whose steps are clipped to land on the grid).
#[test]
fn grid_points_are_exact_on_the_double_integrator_with_both_integrators() {
    let (d, x, u, s) = double_integrator();
    let nodes = 3;
    let substeps = 5;
    for settings in [
        {
            let mut s = DiscretizationSettings::default();
            s.substeps = substeps;
            s
        },
        {
            let mut s = dp(1e-12, 1e-14);
            s.substeps = substeps;
            s
        },
    ] {
        let mut ws = d.workspace();
        let mut out = d.output_with_grid(nodes, substeps);
        d.discretize(&x, &u, &s, &settings, &mut ws, &mut out).unwrap();
        let stride = d.grid_stride();
        // Segment 0 lasts T = s·Δτ = 1 with the acceleration going linearly from 1 to −2.
        for j in 0..=substeps {
            let t = j as f64 / substeps as f64;
            let (a0, a1) = (1.0, -2.0);
            let vel = -0.2 + a0 * t + (a1 - a0) * t * t / 2.0;
            let pos = 0.3 - 0.2 * t + a0 * t * t / 2.0 + (a1 - a0) * t * t * t / 6.0;
            let g = &out.grid[j * stride..j * stride + 2];
            assert!((g[0] - pos).abs() < 1e-12 && (g[1] - vel).abs() < 1e-12, "{j}: {g:?}");
        }
    }
}

/// A grid sized for other substeps is a located size error, not a panic.
#[test]
fn grid_for_other_substeps_is_an_error() {
    let d = nonlinear();
    let nodes = 3;
    let x = vec![0.1; nodes * 3];
    let u = vec![0.2; nodes * 2];
    let s = vec![1.0; nodes];
    let mut ws = d.workspace();
    let mut out = d.output_with_grid(nodes, 4);
    let settings = {
        let mut s = DiscretizationSettings::default();
        s.substeps = 5;
        s
    };
    let e = d.discretize(&x, &u, &s, &settings, &mut ws, &mut out).unwrap_err();
    assert!(
        e.to_string().contains("grid of substeps + 1 points (substeps 5, grid points 5)"),
        "{e}"
    );
}

fn substeps(sub: usize) -> DiscretizationSettings {
    let mut settings = DiscretizationSettings::default();
    settings.substeps = sub;
    settings
}

/// `[A | B⁻ | B⁺ (controls)]` of segment `seg`, `n × (n + 2m + 1)`: the map's Jacobian over
/// `z = [x_k | u_k | s_k | u_{k+1}]`.
fn segment_jacobian(
    d: &Dynamics,
    x: &[f64],
    u: &[f64],
    s: &[f64],
    seg: usize,
    sub: usize,
) -> Vec<f64> {
    let (n, mu) = (d.n_x(), d.n_u());
    let (m, nz) = (mu + 1, n + 2 * mu + 1);
    let settings = substeps(sub);
    let mut out = d.output(s.len());
    d.discretize(x, u, s, &settings, &mut d.workspace(), &mut out).unwrap();
    let mut j = vec![0.0; n * nz];
    for r in 0..n {
        j[r * nz..r * nz + n].copy_from_slice(&out.a[seg * n * n + r * n..][..n]);
        j[r * nz + n..r * nz + n + m].copy_from_slice(&out.b_minus[seg * n * m + r * m..][..m]);
        j[r * nz + n + m..(r + 1) * nz].copy_from_slice(&out.b_plus[seg * n * m + r * m..][..mu]);
    }
    j
}

/// A nonlinear system with a gated row on 4 nodes, its inputs and a weight `y` on a segment's
/// end: the segment Hessians' test case.
struct SegmentCase {
    d: Dynamics,
    x: Vec<f64>,
    u: Vec<f64>,
    s: Vec<f64>,
    y: [f64; 3],
}

fn segment_case() -> SegmentCase {
    segment_case_of(nonlinear())
}

fn segment_case_of(d: Dynamics) -> SegmentCase {
    let (n, mu, nodes) = (3, 2, 4);
    SegmentCase {
        d: d.gate(2, 1, 3).unwrap(),
        x: (0..nodes * n).map(|i| (i as f64 * 0.7).sin()).collect(),
        u: (0..nodes * mu).map(|i| (i as f64 * 1.3).cos()).collect(),
        s: vec![1.5, 1.2, 2.0, 2.0],
        y: [0.7, -1.3, 0.4],
    }
}

/// The inputs with entry `col` of segment `seg`'s `z = [x_k | u_k | s_k | u_{k+1}]` moved by
/// `by` (n states; the controls' count follows from `u`).
fn shift_segment_input(
    (x, u, s): (&[f64], &[f64], &[f64]),
    (n, seg, col): (usize, usize, usize),
    by: f64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mu = u.len() / s.len();
    let (mut xs, mut us, mut ss) = (x.to_vec(), u.to_vec(), s.to_vec());
    match col {
        c if c < n => xs[seg * n + c] += by,
        c if c < n + mu => us[seg * mu + c - n] += by,
        c if c == n + mu => ss[seg] += by,
        c => us[(seg + 1) * mu + c - n - mu - 1] += by,
    }
    (xs, us, ss)
}

/// The segment Hessian `yᵀ∂²x_prop/∂z²` (second-order adjoint on the grid) against central
/// differences of the map's exact Jacobians, on every segment of a nonlinear system with a
/// gated row; it converges to them as the grid refines (the RK4 map and the exact flow
/// differ by O(h⁴)).
#[test]
fn segment_hessian_matches_differences_of_the_jacobians() {
    segment_hessian_matches_differences(segment_case());
}

/// The same with a time-scaled control: the transformed `G` (chain factors `s` and 1, the
/// dilation's row and its `(1/s)·uᵀH_uu u` corner) against differences of the exact
/// Jacobians.
#[test]
fn segment_hessian_with_a_time_scaled_control_matches_differences_of_the_jacobians() {
    segment_hessian_matches_differences(segment_case_of(nonlinear_scaled()));
}

/// The largest difference between the symmetric `nz × nz` Hessian `h` and central
/// differences (step 1e-5) of `gradient(col, by)`, the gradient with input `col` shifted by
/// `by`, relative to the differences' largest entry; asserts `h`'s symmetry on the way.
fn against_differences(h: &[f64], nz: usize, gradient: impl Fn(usize, f64) -> Vec<f64>) -> f64 {
    let eps = 1e-5;
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for col in 0..nz {
        let (gp, gm) = (gradient(col, eps), gradient(col, -eps));
        for r in 0..nz {
            let fd = (gp[r] - gm[r]) / (2.0 * eps);
            worst = worst.max((h[col * nz + r] - fd).abs());
            scale = scale.max(fd.abs());
            let asymmetry = (h[col * nz + r] - h[r * nz + col]).abs();
            assert!(asymmetry <= 1e-12 * (1.0 + h[col * nz + r].abs()), "({col}, {r})");
        }
    }
    worst / scale
}

fn segment_hessian_matches_differences(case: SegmentCase) {
    let SegmentCase { d, x, u, s, y } = case;
    let (n, nodes) = (3, 4);
    let nz = n + 2 * d.n_u() + 1;
    let error_at = |sub: usize, seg: usize| {
        let settings = substeps(sub);
        let mut out = d.output_with_grid(nodes, sub);
        d.discretize(&x, &u, &s, &settings, &mut d.workspace(), &mut out).unwrap();
        let mut h = vec![0.0; nz * nz];
        let mut ws = d.segment_hessian_workspace();
        d.segment_hessian(&out, seg, &u, s[seg], &y, &mut ws, &mut h).unwrap();
        against_differences(&h, nz, |col, by| {
            let (xs, us, ss) = shift_segment_input((&x, &u, &s), (n, seg, col), by);
            let j = segment_jacobian(&d, &xs, &us, &ss, seg, sub);
            (0..nz).map(|r| (0..n).map(|i| y[i] * j[i * nz + r]).sum()).collect()
        })
    };
    for seg in 0..nodes - 1 {
        let (coarse, fine) = (error_at(4, seg), error_at(40, seg));
        assert!(fine < 2e-6, "segment {seg}: relative error {fine:e} with 40 substeps");
        assert!(fine < coarse / 100.0, "segment {seg}: {coarse:e} → {fine:e} does not converge");
    }
}

/// `Σ_i c_iᵀ ∂x(τ_i)/∂z` over segment `seg`'s grid points (weights `c`, `points × n`): the
/// gradient whose differences give the along-the-grid Hessian.
fn grid_gradient(
    d: &Dynamics,
    (x, u, s): (&[f64], &[f64], &[f64]),
    (seg, sub): (usize, usize),
    c: &[f64],
) -> Vec<f64> {
    let (n, mu) = (d.n_x(), d.n_u());
    let (m, nz, stride) = (mu + 1, n + 2 * mu + 1, d.grid_stride());
    let mut out = d.output_with_grid(s.len(), sub);
    d.discretize(x, u, s, &substeps(sub), &mut d.workspace(), &mut out).unwrap();
    let mut g = vec![0.0; nz];
    for i in 0..=sub {
        let at = &out.grid[(seg * (sub + 1) + i) * stride..][..stride];
        let (phi, bm, bp) = (&at[n..], &at[n + n * n..], &at[n + n * n + n * m..]);
        for r in 0..n {
            let w = c[i * n + r];
            for col in 0..n {
                g[col] += w * phi[r * n + col];
            }
            for col in 0..m {
                g[n + col] += w * bm[r * m + col];
            }
            for col in 0..mu {
                g[n + m + col] += w * bp[r * m + col];
            }
        }
    }
    g
}

/// Weights on the grid points between the nodes (and on the segment's end, as `y`): the
/// Hessian matches central differences of the grid's exact sensitivities, on every segment
/// of a nonlinear system with a gated row, and converges to them as the grid refines.
#[test]
fn segment_hessian_along_the_grid_matches_differences_of_its_sensitivities() {
    segment_hessian_along_matches_differences(segment_case());
}

/// The same with a time-scaled control.
#[test]
fn segment_hessian_along_the_grid_with_a_time_scaled_control_matches_differences() {
    segment_hessian_along_matches_differences(segment_case_of(nonlinear_scaled()));
}

fn segment_hessian_along_matches_differences(case: SegmentCase) {
    let SegmentCase { d, x, u, s, y } = case;
    let (n, nodes) = (3, 4);
    let nz = n + 2 * d.n_u() + 1;
    let error_at = |sub: usize, seg: usize| {
        // A smooth weight profile over the segment, the same on every grid.
        let c: Vec<f64> = (0..=sub)
            .flat_map(|i| {
                let t = i as f64 / sub as f64;
                [(1.0 + 2.0 * t).sin(), 0.5 - t * t, (3.0 * t).cos() * 0.3]
            })
            .map(|w| w / sub as f64)
            .collect();
        let mut with_y = c.clone();
        for r in 0..n {
            with_y[sub * n + r] += y[r];
        }
        let mut out = d.output_with_grid(nodes, sub);
        d.discretize(&x, &u, &s, &substeps(sub), &mut d.workspace(), &mut out).unwrap();
        let mut h = vec![0.0; nz * nz];
        let mut ws = d.segment_hessian_workspace();
        d.segment_hessian_along(&out, seg, &u, s[seg], &y, &c, &mut ws, &mut h).unwrap();
        against_differences(&h, nz, |col, by| {
            let (xs, us, ss) = shift_segment_input((&x, &u, &s), (n, seg, col), by);
            grid_gradient(&d, (&xs, &us, &ss), (seg, sub), &with_y)
        })
    };
    for seg in 0..nodes - 1 {
        let (coarse, mid, fine) = (error_at(4, seg), error_at(7, seg), error_at(40, seg));
        assert!(fine < 2e-6, "segment {seg}: relative error {fine:e} with 40 substeps");
        assert!(mid < coarse, "segment {seg}: {coarse:e} (4) → {mid:e} (7, odd)");
        assert!(fine < coarse / 1000.0, "segment {seg}: {coarse:e} → {fine:e} does not converge");
    }
}

/// The weights' layout is checked: a `points` slice that is neither empty nor one weight
/// vector per grid point is an error.
#[test]
fn segment_hessian_along_refuses_a_wrong_layout() {
    let d = nonlinear();
    let (x, u, s) = (vec![0.1; 9], vec![0.2; 6], vec![1.0; 3]);
    let mut ws = d.segment_hessian_workspace();
    let mut h = vec![0.0; 64];
    let mut grid = d.output_with_grid(3, 4);
    d.discretize(&x, &u, &s, &substeps(4), &mut d.workspace(), &mut grid).unwrap();
    let y = [1.0; 3];
    for bad in [3, 14, 16] {
        let points = vec![0.5; bad];
        let e = d.segment_hessian_along(&grid, 0, &u, 1.0, &y, &points, &mut ws, &mut h);
        assert!(e.unwrap_err().to_string().contains(&format!("points of {bad} (need 0 or 15)")));
    }
    // Weights only on the end point are `y` itself.
    let (mut end_only, mut as_y) = (vec![0.0; 64], vec![0.0; 64]);
    let mut points = vec![0.0; 15];
    points[12..].copy_from_slice(&y);
    d.segment_hessian_along(&grid, 1, &u, 1.0, &[0.0; 3], &points, &mut ws, &mut end_only).unwrap();
    d.segment_hessian(&grid, 1, &u, 1.0, &y, &mut ws, &mut as_y).unwrap();
    assert_eq!(end_only, as_y);
}

/// Bad calls are errors, not panics: no grid, a segment out of range, a wrong `y`.
#[test]
fn segment_hessian_refuses_what_it_cannot_do() {
    let d = nonlinear();
    let (x, u, s) = (vec![0.1; 9], vec![0.2; 6], vec![1.0; 3]);
    let mut ws = d.segment_hessian_workspace();
    let mut h = vec![0.0; 64];
    let mut plain = d.output(3);
    d.discretize(&x, &u, &s, &DiscretizationSettings::default(), &mut d.workspace(), &mut plain)
        .unwrap();
    assert!(d.segment_hessian(&plain, 0, &u, 1.0, &[1.0; 3], &mut ws, &mut h).is_err());
    let mut grid = d.output_with_grid(3, 10);
    d.discretize(&x, &u, &s, &DiscretizationSettings::default(), &mut d.workspace(), &mut grid)
        .unwrap();
    assert!(d.segment_hessian(&grid, 2, &u, 1.0, &[1.0; 3], &mut ws, &mut h).is_err());
    assert!(d.segment_hessian(&grid, 1, &u, 1.0, &[1.0; 2], &mut ws, &mut h).is_err());
    assert!(d.segment_hessian(&grid, 1, &u, 1.0, &[1.0; 3], &mut ws, &mut h).is_ok());
}
