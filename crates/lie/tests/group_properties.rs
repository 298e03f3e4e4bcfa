//! One generic property suite, run for SO(3) and SE(3) over random tangents and the edge
//! cases that break naive implementations: identity, tiny (1e-8), near π and exactly π.
//!
//! Every analytic Jacobian is compared with central finite differences of the group
//! operations themselves (relative error < 1e-6), and `exp` is compared with an independent
//! scaling-and-squaring matrix exponential of `hat(τ)`.

use std::f64::consts::PI;

use armature_lie::{LieGroup, SE3, SO3};
use nalgebra::{SMatrix, SVector, Vector3, Vector6};
use proptest::prelude::*;

/// Central-difference step. Truncation ~h²·|f'''| ≈ 1e-10, round-off ~ε/h ≈ 1e-11.
const H: f64 = 1e-5;
/// Relative tolerance for analytic vs finite-difference Jacobians.
const FD_TOL: f64 = 1e-6;
/// Tolerance for identities that hold exactly up to round-off.
const EXACT_TOL: f64 = 1e-11;

/// Largest absolute entry.
fn amax<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> f64 {
    m.iter().fold(0.0, |a, b| a.max(b.abs()))
}

/// `|a − b|_max / max(1, |a|_max)`.
fn rel_err<const R: usize, const C: usize>(a: &SMatrix<f64, R, C>, b: &SMatrix<f64, R, C>) -> f64 {
    amax(&(a - b)) / amax(a).max(1.0)
}

/// Independent matrix exponential: scaling and squaring of a 20-term Taylor series.
fn expm<const D: usize>(a: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
    let s = (amax(a).max(1e-300).log2().ceil() + 4.0).max(0.0) as i32;
    let a = a / 2f64.powi(s);
    let mut term = SMatrix::<f64, D, D>::identity();
    let mut sum = term;
    for k in 1..=20 {
        term = term * a / k as f64;
        sum += term;
    }
    for _ in 0..s {
        sum = sum * sum;
    }
    sum
}

/// What the suite needs to know about a group beyond the trait.
trait Example<const N: usize, const D: usize>: LieGroup<N, D> + std::fmt::Debug {
    /// Rotation angle of the element `exp(tau)` would be if `|ω| ≤ π` (i.e. `|ω|`).
    fn rotation_angle(tau: &SVector<f64, N>) -> f64;
    /// Jacobians of `act` at `p` w.r.t. the element (right perturbation) and the point,
    /// together with the acted point, as (value, J_X as 3×N, J_p).
    fn act(&self, p: &Vector3<f64>) -> Vector3<f64>;
    fn act_jacobians_dyn(&self, p: &Vector3<f64>) -> (SMatrix<f64, 3, N>, SMatrix<f64, 3, 3>);
    fn dexp_dtangent(tau: &SVector<f64, N>) -> [SMatrix<f64, D, D>; N];
    fn dlog_dmatrix(&self) -> [SMatrix<f64, D, D>; N];
}

impl Example<3, 3> for SO3 {
    fn rotation_angle(tau: &Vector3<f64>) -> f64 {
        tau.norm()
    }
    fn act(&self, p: &Vector3<f64>) -> Vector3<f64> {
        SO3::act(self, p)
    }
    fn act_jacobians_dyn(&self, p: &Vector3<f64>) -> (SMatrix<f64, 3, 3>, SMatrix<f64, 3, 3>) {
        self.act_jacobians(p)
    }
    fn dexp_dtangent(tau: &Vector3<f64>) -> [SMatrix<f64, 3, 3>; 3] {
        SO3::dexp_dtangent_matrix(tau)
    }
    fn dlog_dmatrix(&self) -> [SMatrix<f64, 3, 3>; 3] {
        SO3::dlog_dmatrix(self)
    }
}

impl Example<6, 4> for SE3 {
    fn rotation_angle(tau: &Vector6<f64>) -> f64 {
        tau.fixed_rows::<3>(3).norm()
    }
    fn act(&self, p: &Vector3<f64>) -> Vector3<f64> {
        SE3::act(self, p)
    }
    fn act_jacobians_dyn(&self, p: &Vector3<f64>) -> (SMatrix<f64, 3, 6>, SMatrix<f64, 3, 3>) {
        self.act_jacobians(p)
    }
    fn dexp_dtangent(tau: &Vector6<f64>) -> [SMatrix<f64, 4, 4>; 6] {
        SE3::dexp_dtangent_matrix(tau)
    }
    fn dlog_dmatrix(&self) -> [SMatrix<f64, 4, 4>; 6] {
        SE3::dlog_dmatrix(self)
    }
}

fn unit<const N: usize>(j: usize) -> SVector<f64, N> {
    let mut e = SVector::<f64, N>::zeros();
    e[j] = 1.0;
    e
}

/// Column-by-column central difference of a tangent-valued function of a tangent.
fn fd<const N: usize, const M: usize>(
    f: impl Fn(&SVector<f64, N>) -> SVector<f64, M>,
) -> SMatrix<f64, M, N> {
    let mut j = SMatrix::<f64, M, N>::zeros();
    for c in 0..N {
        let e = unit::<N>(c) * H;
        j.set_column(c, &((f(&e) - f(&-e)) / (2.0 * H)));
    }
    j
}

/// Runs every property on one tangent `tau` and two auxiliary elements.
fn check_all<G: Example<N, D>, const N: usize, const D: usize>(
    tau: SVector<f64, N>,
    aux1: SVector<f64, N>,
    aux2: SVector<f64, N>,
    point: Vector3<f64>,
) {
    let x = G::exp(&tau);
    let y = G::exp(&aux1);
    let z = G::exp(&aux2);
    let angle = G::rotation_angle(&tau);
    let ctx = format!("tau = {tau:?}");

    // exp against an independent matrix exponential.
    let m = x.matrix();
    assert!(rel_err(&expm(&G::hat(&tau)), &m) < 1e-12, "exp vs expm, {ctx}");

    // hat / vee.
    assert!(amax(&(G::vee(&G::hat(&tau)) - tau)) <= EXACT_TOL * tau.amax().max(1.0), "{ctx}");

    // log ∘ exp and exp ∘ log.
    let l = x.log();
    assert!(l.iter().all(|v| v.is_finite()), "log not finite, {ctx}");
    assert!(G::rotation_angle(&l) <= PI + 1e-15, "|ω| > π, {ctx}");
    assert!(rel_err(&G::exp(&l).matrix(), &m) < EXACT_TOL, "exp(log(X)) != X, {ctx}");
    if angle < PI - 1e-6 {
        assert!(amax(&(l - tau)) < 1e-10 * tau.amax().max(1.0), "log(exp(τ)) != τ, {ctx}");
    } else if angle <= PI {
        // At |ω| = π the logarithm is ±ω.
        assert!((G::rotation_angle(&l) - angle).abs() < 1e-9, "{ctx}");
    }

    // Inverse and associativity, also as matrices.
    let xi = x.inverse();
    assert!(amax(&(x.compose(&xi).matrix() - SMatrix::identity())) < EXACT_TOL, "{ctx}");
    assert!(rel_err(&xi.matrix(), &m.try_inverse().unwrap()) < 1e-10, "{ctx}");
    assert!(rel_err(&xi.inverse().matrix(), &m) < EXACT_TOL, "{ctx}");
    assert!(rel_err(&x.compose(&y).matrix(), &(m * y.matrix())) < EXACT_TOL, "{ctx}");
    let (xy_z, x_yz) = (x.compose(&y).compose(&z), x.compose(&y.compose(&z)));
    assert!(rel_err(&xy_z.matrix(), &x_yz.matrix()) < EXACT_TOL, "associativity, {ctx}");
    assert!(
        rel_err(&x.compose(&y).inverse().matrix(), &y.inverse().compose(&xi).matrix()) < EXACT_TOL,
        "{ctx}"
    );

    // Adjoint: X exp(a) X⁻¹ = exp(Ad a), and hat(Ad a) = M hat(a) M⁻¹.
    let ad = x.adjoint();
    let lhs = x.compose(&y).compose(&xi);
    assert!(rel_err(&lhs.matrix(), &G::exp(&(ad * aux1)).matrix()) < 1e-10, "Ad, {ctx}");
    let conj = m * G::hat(&aux1) * m.try_inverse().unwrap();
    assert!(rel_err(&conj, &G::hat(&(ad * aux1))) < 1e-10, "Ad hat, {ctx}");

    // Jacobian identities.
    let (jr, jl) = (G::jr(&tau), G::jl(&tau));
    assert!(amax(&(jr - G::jl(&-tau))) < EXACT_TOL, "jr(τ) != jl(−τ), {ctx}");
    assert!(rel_err(&jl, &(ad * jr)) < 1e-10, "jl != Ad jr, {ctx}");
    if angle < 1.5 * PI {
        let (jri, jli) = (G::jr_inv(&tau), G::jl_inv(&tau));
        assert!(amax(&(jl * jli - SMatrix::identity())) < 1e-10, "jl jl_inv, {ctx}");
        assert!(amax(&(jr * jri - SMatrix::identity())) < 1e-10, "jr jr_inv, {ctx}");
    }

    // Finite differences. jr / jl through exp only (smooth everywhere).
    let fd_jr = fd(|d| G::exp(&(tau + d)).minus(&x));
    assert!(rel_err(&jr, &fd_jr) < FD_TOL, "jr vs FD: {}, {ctx}", rel_err(&jr, &fd_jr));
    let fd_jl = fd(|d| G::exp(&(tau + d)).compose(&xi).log());
    assert!(rel_err(&jl, &fd_jl) < FD_TOL, "jl vs FD, {ctx}");
    assert!(rel_err(&G::exp_jacobian(&tau), &fd_jr) < FD_TOL, "{ctx}");

    // Compose and inverse Jacobians (right perturbations on both sides).
    let xy = x.compose(&y);
    let (jx, jy) = x.compose_jacobians(&y);
    assert!(rel_err(&jx, &fd(|d| x.plus(d).compose(&y).minus(&xy))) < FD_TOL, "{ctx}");
    assert!(rel_err(&jy, &fd(|d| x.compose(&y.plus(d)).minus(&xy))) < FD_TOL, "{ctx}");
    let jinv = x.inverse_jacobian();
    assert!(rel_err(&jinv, &fd(|d| x.plus(d).inverse().minus(&xi))) < FD_TOL, "{ctx}");

    // Action Jacobians.
    let (jax, jap) = x.act_jacobians_dyn(&point);
    let p0 = x.act(&point);
    let mut fd_ax = SMatrix::<f64, 3, N>::zeros();
    for c in 0..N {
        let e = unit::<N>(c) * H;
        fd_ax.set_column(c, &((x.plus(&e).act(&point) - x.plus(&-e).act(&point)) / (2.0 * H)));
    }
    assert!(rel_err(&jax, &fd_ax) < FD_TOL, "act J_X, {ctx}");
    let fd_ap = fd(|d: &Vector3<f64>| x.act(&(point + d)) - p0);
    assert!(rel_err(&jap, &fd_ap) < FD_TOL, "act J_p, {ctx}");

    // Matrix-entry derivative of exp.
    let dexp = G::dexp_dtangent(&tau);
    for (j, dj) in dexp.iter().enumerate() {
        let e = unit::<N>(j) * H;
        let fd_m = (G::exp(&(tau + e)).matrix() - G::exp(&(tau - e)).matrix()) / (2.0 * H);
        assert!(rel_err(dj, &fd_m) < FD_TOL, "dexp/dτ_{j}, {ctx}");
    }

    // log is smooth only away from the cut at |ω| = π.
    if angle < PI - 1e-3 {
        // jr_inv and log_jacobian: d/dδ log(X·exp(δ)).
        let fd_log = fd(|d| x.plus(d).log());
        assert!(rel_err(&G::jr_inv(&tau), &fd_log) < FD_TOL, "jr_inv vs FD, {ctx}");
        assert!(rel_err(&x.log_jacobian(), &fd_log) < FD_TOL, "{ctx}");
        let fd_logl = fd(|d| G::exp(d).compose(&x).log());
        assert!(rel_err(&G::jl_inv(&tau), &fd_logl) < FD_TOL, "jl_inv vs FD, {ctx}");

        // dlog/dM along a left-perturbed curve M(h) = exp(h a)·M (a direction the formula was
        // not derived from), and the chain rule log(exp(τ)) = τ ⇒ Σ⟨G_i, ∂M/∂τ_j⟩ = δ_ij.
        let g = x.dlog_dmatrix();
        let a = aux1 / aux1.norm().max(1e-300);
        let dm = G::hat(&a) * m;
        let analytic = SVector::<f64, N>::from_fn(|i, _| g[i].component_mul(&dm).sum());
        let fd_curve =
            (G::exp(&(a * H)).compose(&x).log() - G::exp(&(a * -H)).compose(&x).log()) / (2.0 * H);
        if aux1.norm() > 1e-6 {
            assert!(amax(&(analytic - fd_curve)) < FD_TOL, "dlog/dM curve, {ctx}");
        }
        let chain = SMatrix::<f64, N, N>::from_fn(|i, j| g[i].component_mul(&dexp[j]).sum());
        assert!(amax(&(chain - SMatrix::identity())) < 1e-9, "dlog∘dexp != I, {ctx}");
    }
}

/// Rotation vectors of the kinds that matter: general, zero, tiny, near π, exactly π.
fn rotation_vector() -> impl Strategy<Value = Vector3<f64>> {
    let axis = (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0)
        .prop_filter("nonzero axis", |(x, y, z)| x * x + y * y + z * z > 1e-4)
        .prop_map(|(x, y, z)| Vector3::new(x, y, z).normalize());
    prop_oneof![
        4 => (axis.clone(), 0.0..PI).prop_map(|(a, t)| a * t),
        1 => Just(Vector3::zeros()),
        1 => (axis.clone(), 1e-10f64..1e-6).prop_map(|(a, t)| a * t),
        1 => (axis.clone(), 1e-12f64..1e-3).prop_map(|(a, d)| a * (PI - d)),
        1 => axis.prop_map(|a| a * PI),
    ]
}

fn twist() -> impl Strategy<Value = Vector6<f64>> {
    (rotation_vector(), prop::array::uniform3(-2.0f64..2.0))
        .prop_map(|(w, v)| Vector6::new(v[0], v[1], v[2], w.x, w.y, w.z))
}

fn point() -> impl Strategy<Value = Vector3<f64>> {
    prop::array::uniform3(-1.0f64..1.0).prop_map(Vector3::from)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(384))]

    #[test]
    fn so3_properties(t in rotation_vector(), a in rotation_vector(), b in rotation_vector(), p in point()) {
        check_all::<SO3, 3, 3>(t, a, b, p);
    }

    #[test]
    fn se3_properties(t in twist(), a in twist(), b in twist(), p in point()) {
        check_all::<SE3, 6, 4>(t, a, b, p);
    }
}

/// The named edge cases, deterministically, for both groups.
#[test]
fn edge_cases_both_groups() {
    let d = Vector3::new(1.0, 2.0, -2.0) / 3.0;
    let axes = [Vector3::x(), Vector3::y(), Vector3::z(), -Vector3::y(), d];
    let mut cases = vec![Vector3::zeros()];
    for a in axes {
        for t in [1e-8, 1e-4, SMALL_ANGLE_EDGE, 0.2, 1.0, PI - 1e-3, PI - 1e-9, PI - 1e-12, PI] {
            cases.push(a * t);
        }
    }
    let aux = Vector3::new(0.3, -0.2, 0.9);
    let p = Vector3::new(0.1, 0.5, -0.4);
    for w in &cases {
        check_all::<SO3, 3, 3>(*w, aux, -aux, p);
        let xi = Vector6::new(0.4, -1.3, 0.7, w.x, w.y, w.z);
        let ax = Vector6::new(-0.5, 0.2, 0.1, aux.x, aux.y, aux.z);
        check_all::<SE3, 6, 4>(xi, ax, -ax, p);
        // A pure translation and a pure rotation twist.
        check_all::<SE3, 6, 4>(Vector6::new(0.0, 0.0, 0.0, w.x, w.y, w.z), ax, ax, p);
    }
    check_all::<SE3, 6, 4>(Vector6::new(0.3, 0.2, -0.1, 0.0, 0.0, 0.0), aux6(), -aux6(), p);
}

const SMALL_ANGLE_EDGE: f64 = armature_lie::SMALL_ANGLE;

fn aux6() -> Vector6<f64> {
    Vector6::new(0.1, 0.2, 0.3, -0.4, 0.5, 0.6)
}
