//! Exact closest points between a capsule and another shape, with the segment parameters
//! the gradient needs.

use armature_lie::SE3;
use nalgebra::Vector3;
use parry3d_f64::math::Vector;
use parry3d_f64::query;
use parry3d_f64::shape::{Segment, SegmentPointLocation};

/// Closest features of two shapes.
///
/// `distance` is signed (surface to surface, negative when penetrating); `normal` is the unit
/// direction in which A moving away from B increases the distance; `s` and `t` locate the
/// closest points on the axis segments of A and B (`p = (1 − s)·start + s·end`), so that the
/// distance's derivative w.r.t. the segment endpoints is
/// `∂d/∂a₀ = (1 − s) n`, `∂d/∂a₁ = s n`, `∂d/∂b₀ = −(1 − t) n`, `∂d/∂b₁ = −t n` (envelope
/// theorem: exact wherever the closest points are unique).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// Signed surface distance (m).
    pub distance: f64,
    /// Witness point on the surface of A.
    pub point_a: Vector3<f64>,
    /// Witness point on the surface of B.
    pub point_b: Vector3<f64>,
    /// Unit normal from B to A.
    pub normal: Vector3<f64>,
    /// Parameter of the closest point on A's segment.
    pub s: f64,
    /// Parameter of the closest point on B's segment (0 for shapes without one).
    pub t: f64,
}

fn to_glam(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x, v.y, v.z)
}

fn from_glam(v: Vector) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

fn param(loc: &SegmentPointLocation) -> f64 {
    match *loc {
        SegmentPointLocation::OnVertex(0) => 0.0,
        SegmentPointLocation::OnVertex(_) => 1.0,
        SegmentPointLocation::OnEdge([_, v]) => v,
    }
}

/// A unit vector for the degenerate case where the axes touch (zero centre distance): the
/// common perpendicular of the two directions, else any perpendicular of A's direction, else
/// +z. A documented, finite choice where the distance is not differentiable.
fn fallback_normal(da: &Vector3<f64>, db: &Vector3<f64>) -> Vector3<f64> {
    let c = da.cross(db);
    if c.norm() > 1e-12 {
        return c.normalize();
    }
    if da.norm() > 1e-12 {
        let p = da.cross(&Vector3::x());
        let p = if p.norm() > 1e-9 { p } else { da.cross(&Vector3::y()) };
        return p.normalize();
    }
    Vector3::z()
}

fn finish(
    pa: Vector3<f64>,
    pb: Vector3<f64>,
    ra: f64,
    rb: f64,
    s: f64,
    t: f64,
    fallback: impl FnOnce() -> Vector3<f64>,
) -> Closest {
    let d = pa - pb;
    let len = d.norm();
    // The fallback only where the axes touch: it costs three square roots.
    let normal = if len > 1e-12 { d / len } else { fallback() };
    Closest {
        distance: len - ra - rb,
        point_a: pa - normal * ra,
        point_b: pb + normal * rb,
        normal,
        s,
        t,
    }
}

/// Capsule `[a0, a1]`, radius `ra`, against capsule `[b0, b1]`, radius `rb`: exact, from
/// parry's segment–segment closest points. Zero-length capsules are spheres.
pub fn capsule_capsule(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    ra: f64,
    b0: &Vector3<f64>,
    b1: &Vector3<f64>,
    rb: f64,
) -> Closest {
    let (la, lb) = query::details::closest_points_segment_segment_with_locations_nD(
        (&to_glam(a0), &to_glam(a1)),
        (&to_glam(b0), &to_glam(b1)),
    );
    let pa = from_glam(Segment::new(to_glam(a0), to_glam(a1)).point_at(&la));
    let pb = from_glam(Segment::new(to_glam(b0), to_glam(b1)).point_at(&lb));
    finish(pa, pb, ra, rb, param(&la), param(&lb), || fallback_normal(&(a1 - a0), &(b1 - b0)))
}

/// Capsule against a sphere (centre `c`, radius `r`): exact closest point on the segment.
pub fn capsule_sphere(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    ra: f64,
    c: &Vector3<f64>,
    r: f64,
) -> Closest {
    let d = a1 - a0;
    let l2 = d.norm_squared();
    let s = if l2 > 0.0 { ((c - a0).dot(&d) / l2).clamp(0.0, 1.0) } else { 0.0 };
    finish(a0 + d * s, *c, ra, r, s, 0.0, || fallback_normal(&d, &Vector3::zeros()))
}

/// Capsule against the half-space `{x : n·x ≤ offset}` (e.g. below a table at height
/// `offset` with `n = +z` pointing into free space): the distance is
/// `min(n·a₀, n·a₁) − offset − r`.
pub fn capsule_halfspace(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    ra: f64,
    n: &Vector3<f64>,
    offset: f64,
) -> Closest {
    let (h0, h1) = (n.dot(a0) - offset, n.dot(a1) - offset);
    let (s, p, h) = if h1 < h0 { (1.0, a1, h1) } else { (0.0, a0, h0) };
    Closest { distance: h - ra, point_a: p - n * ra, point_b: p - n * h, normal: *n, s, t: 0.0 }
}

/// Signed distance from `p` to the box (negative inside) and its unit gradient (world).
fn point_box(p: &Vector3<f64>, pose: &SE3, half: &Vector3<f64>) -> (f64, Vector3<f64>) {
    let r = pose.rotation().matrix();
    let l = r.transpose() * (p - pose.translation());
    let q = Vector3::new(l.x.abs() - half.x, l.y.abs() - half.y, l.z.abs() - half.z);
    let outside = q.map(|x| x.max(0.0));
    let sign = l.map(|x| if x < 0.0 { -1.0 } else { 1.0 });
    let on = outside.norm();
    if on > 0.0 {
        (on, r * outside.component_mul(&sign) / on)
    } else {
        // Inside: the nearest face.
        let k = if q.x >= q.y && q.x >= q.z {
            0
        } else if q.y >= q.z {
            1
        } else {
            2
        };
        let mut n = Vector3::zeros();
        n[k] = sign[k];
        (q[k], r * n)
    }
}

/// Capsule against a box (`pose` of its centre, `half_extents`). The signed distance to a
/// convex set is convex, so along the capsule axis `min_s sd(a(s))` is a one-dimensional
/// convex problem: bisection on the sign of its derivative gives the minimiser `s` to full
/// precision, and with it the exact distance and the gradient. (parry3d-f64 0.31 has no capsule–cuboid contact query in
/// its light feature set, and its GJK closest points are accurate to ~1e-6 only and unsigned.)
pub fn capsule_box(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    ra: f64,
    pose: &SE3,
    half_extents: &Vector3<f64>,
) -> Closest {
    let d = a1 - a0;
    // g(s) = ∇sd(a(s))·d is non-decreasing (sd is convex along the line) and, unlike sd
    // itself near its minimum, computed to full precision: bisect on its sign.
    let g = |s: f64| point_box(&(a0 + d * s), pose, half_extents).1.dot(&d);
    let s = if d.norm_squared() == 0.0 || g(0.0) >= 0.0 {
        0.0
    } else if g(1.0) <= 0.0 {
        1.0
    } else {
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if g(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    };
    let p = a0 + d * s;
    let (dist, normal) = point_box(&p, pose, half_extents);
    Closest {
        distance: dist - ra,
        point_a: p - normal * ra,
        point_b: p - normal * dist,
        normal,
        s,
        t: 0.0,
    }
}
