//! Evaluating the nodal and interval constraints at the nodes and on the integration grid,
//! with their Jacobians; propagation and linearization of the dynamics.

use super::*;

/// Scratch for evaluating the nodal constraints (allocated once per solve).
#[derive(Debug)]
pub(super) struct NodalEval {
    /// Per-lane scratch (one lane per rayon worker; see [`for_lanes`]).
    pub(super) lanes: Vec<EvalLane>,
    pub(super) values: Vec<f64>,
    pub(super) jac: Vec<f64>,
    /// Per nodal buffer, then per peak row: its positive violation.
    pub(super) violation: Vec<f64>,
    /// Per peak buffer: the largest positive violation of its rows.
    pub(super) buffer_violation: Vec<f64>,
    /// Coefficients of the interval-bound rows (`Source::Peak`) at the last `fill_peaks`.
    pub(super) peak_vals: Vec<f64>,
    /// Each interval-bound row's `sign·x̂ − bound` at the last `fill_peaks`.
    pub(super) peak_g: Vec<f64>,
    /// Interval constraints: their values and (when linearized) Jacobian nonzeros at every
    /// grid point of their segments (see [`IntervalMeta`]).
    pub(super) fgrid: Vec<f64>,
    pub(super) fjac: Vec<f64>,
    /// Per grid point of `fgrid`: its Jacobian is needed by the current `fill_peaks`.
    pub(super) fjac_at: Vec<bool>,
    /// The grid points whose Jacobians `fill_peaks` evaluates (capacity: every point).
    pub(super) stencil_points: Vec<usize>,
    /// Per peak row: the first grid point of its stencil and its weights, at the last
    /// `fill_peaks`.
    pub(super) stencils: Vec<(usize, Stencil)>,
    /// Per peak row: where its peak lies, at the last `fill_peaks` (`None` on a grid of
    /// fewer than three points).
    pub(super) vertices: Vec<Option<Vertex>>,
    /// `fgrid` holds the interval constraints' values at the reference (`Iterate::dbar`):
    /// set when they are evaluated there, or when the candidate they were evaluated at is
    /// accepted; cleared by an evaluation anywhere else and by a parameter change.
    pub(super) fgrid_reference: bool,
    /// Per interval constraint and segment: its largest peak at the last `fill_peaks`.
    pub(super) segment_peak: Vec<f64>,
}

/// Where an evaluation of the interval constraints is: at the reference, whose values
/// [`NodalEval::fgrid`] may already hold, or anywhere else.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum GridAt {
    Reference,
    Other,
}

/// One lane's evaluation scratch: a workspace per nodal and per interval constraint, and the
/// function input `[x; u]`.
#[derive(Debug)]
pub(super) struct EvalLane {
    pub(super) ws: Vec<armature_symbolic::Workspace>,
    pub(super) iws: Vec<armature_symbolic::Workspace>,
    pub(super) input: Vec<f64>,
}

/// Runs `f(lane, jobs, vals, jacs)` over the jobs `0..count` split into contiguous chunks of
/// about equal total `weight`, one per lane: the first on the calling thread, the others
/// spawned on the rayon pool (one small allocation each, as the discretization's lanes).
/// Job `j`'s outputs start at `offsets(j)` in `vals` and in `jacs`, non-decreasing in `j`
/// (`offsets(count)`: where the last job's end); each chunk gets the parts of both buffers
/// from its first job's offsets up to the next chunk's.
pub(super) fn for_lanes<F>(
    lanes: &mut [EvalLane],
    count: usize,
    weight: impl Fn(usize) -> usize,
    offsets: impl Fn(usize) -> (usize, usize),
    vals: &mut [f64],
    jacs: &mut [f64],
    f: F,
) where
    F: Fn(&mut EvalLane, std::ops::Range<usize>, &mut [f64], &mut [f64]) + Sync,
{
    let (v0, j0) = offsets(0);
    let (mut vals, mut jacs) = (&mut vals[v0..], &mut jacs[j0..]);
    let lanes_used = lanes.len().min(count).max(1);
    if lanes_used == 1 {
        f(&mut lanes[0], 0..count, vals, jacs);
        return;
    }
    let (mut at, mut start) = ((v0, j0), 0);
    let total: usize = (0..count).map(&weight).sum();
    let (mut done, f) = (0, &f);
    rayon::in_place_scope(|scope| {
        let mut first = None;
        for (i, lane) in lanes[..lanes_used].iter_mut().enumerate() {
            let mut end = start;
            let target = total * (i + 1) / lanes_used;
            while end < count && (done < target || i + 1 == lanes_used) {
                done += weight(end);
                end += 1;
            }
            let next = offsets(end);
            let (mine_v, rest_v) = std::mem::take(&mut vals).split_at_mut(next.0 - at.0);
            let (mine_j, rest_j) = std::mem::take(&mut jacs).split_at_mut(next.1 - at.1);
            (vals, jacs, at) = (rest_v, rest_j, next);
            let range = start..end;
            start = end;
            if i == 0 {
                first = Some((lane, range, mine_v, mine_j));
            } else {
                scope.spawn(move |_| f(lane, range, mine_v, mine_j));
            }
        }
        if let Some((lane, range, v, j)) = first {
            f(lane, range, v, j);
        }
    });
}

/// The constraint matrix's values from their sources at one linearization.
pub(super) fn fill_values(
    sources: &[Source],
    d: &Discretization,
    ev: &NodalEval,
    peak_vals: &[f64],
    out: &mut [f64],
) {
    for (v, src) in out.iter_mut().zip(sources) {
        *v = match *src {
            Source::Const(c) => c,
            Source::A(i) => d.a[i],
            Source::Bm(i) => d.b_minus[i],
            Source::Bp(i) => d.b_plus[i],
            Source::G(i) => ev.jac[i],
            Source::NegG(i) => -ev.jac[i],
            Source::Peak(i) => peak_vals[i],
        };
    }
}

/// The weights of a peak row's value over consecutive grid points from its stencil's first:
/// three for the parabola, up to five with the cubic margin's third differences.
pub(super) const STENCIL: usize = 5;

/// A peak row's weights (see [`STENCIL`]).
pub(super) type Stencil = [f64; STENCIL];

/// The parabola's weights at `θ` (relative to its centre) as a stencil from its first point.
fn parabola(theta: f64) -> Stencil {
    [0.5 * theta * (theta - 1.0), 1.0 - theta * theta, 0.5 * theta * (theta + 1.0), 0.0, 0.0]
}

/// `Σ w_i g(first + i)` over the nonzero weights.
fn weighed(first: usize, w: &Stencil, g: &impl Fn(usize) -> f64) -> f64 {
    w.iter().enumerate().filter(|(_, w)| **w != 0.0).map(|(i, w)| w * g(first + i)).sum()
}

/// The peak of `g` over the grid points `0..pts`, bounded from above: `(ĝ, first grid point
/// of the stencil, its weights)`. The discrete maximum is refined by the parabola through it
/// and its neighbours (the vertex, when the parabola is concave and the vertex lies between
/// them), plus a bound on what the parabola misses of a cubic (`cubic_margin`); `ĝ = Σ w_i
/// g_i`.
pub(super) fn peak_of(pts: usize, g: impl Fn(usize) -> f64) -> (f64, usize, Stencil) {
    if pts < 3 {
        let best = (1..pts).fold(0, |b, j| if g(j) > g(b) { j } else { b });
        return (g(best), best, [1.0, 0.0, 0.0, 0.0, 0.0]);
    }
    let v = vertex(pts, None, &g);
    bounded_parabola(pts, v.centre, v.theta, &g)
}

/// Where a peak row's parabola is at its largest: its centre `c` (it runs through
/// `c − 1, c, c + 1`), the offset `θ` from `c` in grid steps, and the parabola's second
/// difference `g(c−1) − 2g(c) + g(c+1)`. For the segment's peak (`at: None`) the parabola is
/// centred on the largest grid value and θ ranges over [−1, 1]; for grid point `at = j` it is
/// centred on j (on its inner neighbour at the segment's ends) and θ ranges over j's cell.
/// θ is the vertex where the parabola is concave, clamped to its range, else the point
/// itself. At least three points.
#[derive(Debug, Clone, Copy)]
pub(super) struct Vertex {
    pub(super) centre: usize,
    pub(super) theta: f64,
    pub(super) second_difference: f64,
    /// Whether θ is the parabola's vertex strictly inside its range (not clamped, not a
    /// convex parabola's point): there the peak's value is smooth in the three values.
    pub(super) interior: bool,
}

/// The [`Vertex`] of the peak of `g` over `0..pts` (`at: None`) or of grid point `at`'s cell.
pub(super) fn vertex(
    pts: usize,
    at: Option<usize>,
    g: &(impl Fn(usize) -> f64 + ?Sized),
) -> Vertex {
    let (c, lo, hi, own) = match at {
        None => {
            let best = (1..pts).fold(0, |b, j| if g(j) > g(b) { j } else { b });
            let c = best.clamp(1, pts - 2);
            (c, -1.0, 1.0, best as f64 - c as f64)
        }
        Some(0) => (1, -1.0, -0.5, -1.0),
        Some(j) if j + 1 >= pts => (pts - 2, 0.5, 1.0, 1.0),
        Some(j) => (j, -0.5, 0.5, 0.0),
    };
    let (gm, g0, gp) = (g(c - 1), g(c), g(c + 1));
    let curv = gm - 2.0 * g0 + gp;
    let raw = if curv < 0.0 { 0.5 * (gm - gp) / curv } else { f64::NAN };
    let interior = raw > lo && raw < hi;
    let theta = if curv < 0.0 { raw.clamp(lo, hi) } else { own };
    Vertex { centre: c, theta, second_difference: curv, interior }
}

/// The parabola through `c − 1, c, c + 1` at `θ` plus the cubic margin, as a stencil from two
/// points before `c` (where there are two): (value, the stencil's first point, its weights).
fn bounded_parabola(
    pts: usize,
    c: usize,
    theta: f64,
    g: &impl Fn(usize) -> f64,
) -> (f64, usize, Stencil) {
    let first = c.saturating_sub(2);
    let mut w = [0.0; STENCIL];
    let at = c - 1 - first;
    w[at..at + 3].copy_from_slice(&parabola(theta)[..3]);
    cubic_margin(pts, c, first, g, &mut w);
    (weighed(first, &w, g), first, w)
}

/// The largest value of `g` within half a grid step of grid point `j` of `pts` (on the
/// segment: the first and last points reach half a step inward), bounded from above: the
/// parabola through three neighbouring points at its largest in `j`'s cell (its vertex
/// where it is concave, clamped into the cell, else `j`), plus a bound on what the parabola
/// misses of a cubic (`cubic_margin`). As `peak_of`: (value, the stencil's first point, its
/// weights), the value `Σ w_i g_i` up to the margin's sign, which is fixed where the weights
/// are taken. The rows of all the grid points so hold the constraint everywhere between
/// them, to fourth order in the grid step — the cells next to the nodes included.
pub(super) fn local_peak(pts: usize, j: usize, g: impl Fn(usize) -> f64) -> (f64, usize, Stencil) {
    if pts < 3 {
        return (g(j), j, [1.0, 0.0, 0.0, 0.0, 0.0]);
    }
    let v = vertex(pts, Some(j), &g);
    bounded_parabola(pts, v.centre, v.theta, &g)
}

/// Adds to `w` (a stencil from `first`) a bound on what the parabola through `c − 1, c,
/// c + 1` misses within a step of `c`: its error at `θ` is `g‴(ξ)·θ(θ² − 1)/6`, at most
/// `max|g‴|/15` in magnitude for `|θ| ≤ 1`, with `g‴` (per grid step cubed) taken as the
/// larger third difference `|Δ³g|` of the two four-point windows around `c` that lie on the
/// segment — as weights, `±(−1, 3, −3, 1)/15` on that window (none with fewer than four
/// points).
fn cubic_margin(pts: usize, c: usize, first: usize, g: &impl Fn(usize) -> f64, w: &mut Stencil) {
    if pts < 4 {
        return;
    }
    // The third difference, zero where it is rounding (a quadratic: a velocity under a
    // first-order hold), so that its sign does not flicker.
    let d3 = |a: usize| {
        let (g0, g1, g2, g3) = (g(a), g(a + 1), g(a + 2), g(a + 3));
        let d = g3 - 3.0 * g2 + 3.0 * g1 - g0;
        let scale = g0.abs() + 3.0 * g1.abs() + 3.0 * g2.abs() + g3.abs();
        if d.abs() <= 1e-12 * scale { 0.0 } else { d }
    };
    let windows = [(c >= 2).then(|| c - 2), (c + 2 < pts).then(|| c - 1)];
    let Some((a, d)) = windows
        .into_iter()
        .flatten()
        .map(|a| (a, d3(a)))
        .max_by(|x, y| x.1.abs().total_cmp(&y.1.abs()))
    else {
        return;
    };
    if d == 0.0 {
        return;
    }
    let sign = if d < 0.0 { -1.0 } else { 1.0 };
    for (i, k) in [-1.0, 3.0, -3.0, 1.0].into_iter().enumerate() {
        w[a - first + i] += sign * k / 15.0;
    }
}

impl Ptr {
    /// Evaluates every nodal constraint at `(x, u)` into the buffers (values, with `jac` their
    /// Jacobians, and per-buffer violations); returns `(Σ w·violation, largest violation)`.
    pub(super) fn eval_nodal(
        &self,
        x: &[f64],
        u: &[f64],
        ev: &mut NodalEval,
        weights: &[f64],
        jac: bool,
    ) -> (f64, f64) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let blocks = &self.nodal_blocks;
        let offsets = |e: usize| if e < blocks.len() { self.g_offsets[e] } else { self.g_len };
        let weight = |e: usize| self.ocp.nodal[blocks[e].0].function.instruction_count();
        let lanes = self.eval_lanes(&mut ev.lanes);
        let (values, jacs) = (&mut ev.values[..], &mut ev.jac[..]);
        for_lanes(lanes, blocks.len(), weight, offsets, values, jacs, |lane, range, vals, jv| {
            let (v0, j0) = offsets(range.start);
            for e in range {
                let (ci, k) = blocks[e];
                let f = &self.ocp.nodal[ci].function;
                let (nout, nnz) = (f.n_outputs(), f.jacobian_pattern().nnz());
                lane.input[..n].copy_from_slice(&x[k * n..(k + 1) * n]);
                lane.input[n..n + m].copy_from_slice(&u[k * m..(k + 1) * m]);
                let (vo, jo) = self.g_offsets[e];
                let out = &mut vals[vo - v0..vo - v0 + nout];
                let jac = jac.then(|| &mut jv[jo - j0..jo - j0 + nnz]);
                // Compiled against the dynamics' groups: evaluation cannot fail on sizes.
                if f.eval(&lane.input[..n + m], &mut lane.ws[ci], out, jac).is_err() {
                    out.fill(f64::INFINITY);
                }
            }
        });
        let (mut sum, mut max) = (0.0, 0.0f64);
        for (i, &(eval, ci, out)) in self.buffers.iter().enumerate() {
            let c = &self.ocp.nodal[ci];
            let vo = self.g_offsets[eval].0;
            let v = match (out, c.kind) {
                (Some(o), _) => ev.values[vo + o],
                (None, kind @ NodalKind::Ball { .. }) => {
                    kind.excess(&ev.values[vo..vo + c.function.n_outputs()])
                }
                (None, NodalKind::Inequality) => 0.0,
            };
            ev.violation[i] = v.max(0.0);
            sum += weights[i] * v.max(0.0);
            max = max.max(v);
        }
        (sum, max)
    }

    /// The interval-bound rows' coefficients at `d` (with its grid sensitivities) into
    /// `ev.peak_vals`: `sign·Σ w_i ∂x_r(t_i)/∂z` over the peak's stencil; their values
    /// `sign·x̂ − bound` into `ev.peak_g`.
    pub(super) fn fill_peaks(&self, d: &Discretization, ev: &mut NodalEval, at: GridAt) {
        let (stride, pts) = (self.ocp.dynamics.grid_stride(), d.grid_points);
        self.eval_interval(d, ev, at);
        // Each peak, and each interval constraint's largest peak per segment (its activation).
        ev.segment_peak.fill(f64::NEG_INFINITY);
        for (i, p) in self.peaks.iter().enumerate() {
            let ((g, first, w), vertex) = self.peak_and_vertex(d, ev, p);
            (ev.peak_g[i], ev.stencils[i], ev.vertices[i]) = (g, (first, w), vertex);
            if let PeakOf::Function { c, .. } = p.of {
                let k = self.intervals[c].seg0 + p.seg - self.intervals[c].first;
                ev.segment_peak[k] = ev.segment_peak[k].max(g);
            }
        }
        // Jacobians only at the active rows' stencil points, once each.
        self.stencil_jacobians(d, ev);
        for (i, p) in self.peaks.iter().enumerate() {
            let (first, w) = ev.stencils[i];
            let base = (p.seg * pts + first) * stride;
            match p.of {
                PeakOf::State(_) => {
                    for q in p.src.clone() {
                        let off = base + self.peak_src[q];
                        let v: f64 = (0..STENCIL)
                            .filter(|&i| w[i] != 0.0)
                            .map(|i| w[i] * d.grid[off + i * stride])
                            .sum();
                        ev.peak_vals[q] = p.sign * v;
                    }
                }
                PeakOf::Function { c, out } => {
                    // Σ_i w_i Σ_r ∂g_o/∂x_r(t_i) · ∂x_r(t_i)/∂z_col; zero when switched off.
                    let meta = &self.intervals[c];
                    ev.peak_vals[p.src.clone()].fill(0.0);
                    if !self.row_active(ev, p) {
                        continue;
                    }
                    for (i, &wi) in w.iter().enumerate().filter(|(_, w)| **w != 0.0) {
                        let point = (p.seg - meta.first) * pts + first + i;
                        let jac = &ev.fjac[meta.jac0 + point * meta.nnz..][..meta.nnz];
                        let block = base + i * stride;
                        for q in p.src.clone() {
                            let (off, rs) = (block + self.peak_src[q], self.peak_stride[q]);
                            let v: f64 = meta.deps[out]
                                .iter()
                                .map(|&(r, jq)| jac[jq] * d.grid[off + r * rs])
                                .sum();
                            ev.peak_vals[q] += wi * v;
                        }
                    }
                }
            }
        }
    }

    /// Whether interval-constraint peak row `p` is in the subproblem at the last
    /// `fill_peaks`: its constraint's largest peak on its segment lies within the
    /// constraint's activation distance of the bound ([`IntervalConstraint::activation`]).
    pub(super) fn row_active(&self, ev: &NodalEval, p: &PeakRow) -> bool {
        let PeakOf::Function { c, .. } = p.of else { return true };
        let meta = &self.intervals[c];
        ev.segment_peak[meta.seg0 + p.seg - meta.first] > -meta.activation
    }

    /// The interval constraints' values at every grid point of their segments of `d`, into
    /// `ev.fgrid`; nothing to do when `d` is the reference's and `ev.fgrid` already holds its
    /// values (`at`).
    pub(super) fn eval_interval(&self, d: &Discretization, ev: &mut NodalEval, at: GridAt) {
        if at == GridAt::Reference && ev.fgrid_reference {
            return;
        }
        let (lanes, grid, jacs) = (self.eval_lanes(&mut ev.lanes), &mut ev.fgrid, &mut ev.fjac);
        self.eval_grid(d, lanes, (grid, jacs), ev.fjac_at.len(), |i| i, false);
        ev.fgrid_reference = at == GridAt::Reference;
    }

    /// The interval constraints' Jacobians at the grid points of the active peak rows'
    /// stencils (`ev.stencils`, at `d`), each point once, into `ev.fjac`; `ev.fjac_at` marks
    /// them.
    pub(super) fn stencil_jacobians(&self, d: &Discretization, ev: &mut NodalEval) {
        let pts = d.grid_points;
        ev.fjac_at.fill(false);
        for ((p, &(first, w)), v) in self.peaks.iter().zip(&ev.stencils).zip(&ev.vertices) {
            if let PeakOf::Function { c, .. } = p.of {
                if !self.row_active(ev, p) {
                    continue;
                }
                let meta = &self.intervals[c];
                let at = meta.pt0 + (p.seg - meta.first) * pts;
                for (i, _) in w.iter().enumerate().filter(|(_, w)| **w != 0.0) {
                    ev.fjac_at[at + first + i] = true;
                }
                // All three of the parabola's points where its vertex moves with them (the
                // vertex's curvature reads them, `peak_envelope.rs`), a zero weight included.
                if let Some(v) = v.filter(|v| v.interior) {
                    ev.fjac_at[at + v.centre - 1..at + v.centre + 2].fill(true);
                }
            }
        }
        ev.stencil_points.clear();
        let marked = ev.fjac_at.iter().enumerate().filter(|(_, at)| **at);
        ev.stencil_points.extend(marked.map(|(gp, _)| gp));
        let (points, lanes) = (&ev.stencil_points, self.eval_lanes(&mut ev.lanes));
        let (grid, jacs) = (&mut ev.fgrid, &mut ev.fjac);
        self.eval_grid(d, lanes, (grid, jacs), points.len(), |i| points[i], true);
    }

    /// The interval constraints at the grid points `point(0)`, …, `point(count − 1)`
    /// (ascending, numbered as `fjac_at`) of `d` on the `lanes`: values into `grid` and, with
    /// `jac`, Jacobian nonzeros into `jacs` (`NodalEval::fgrid` and `fjac`).
    pub(super) fn eval_grid(
        &self,
        d: &Discretization,
        lanes: &mut [EvalLane],
        (grid, jacs): (&mut [f64], &mut [f64]),
        count: usize,
        point: impl Fn(usize) -> usize + Sync,
        jac: bool,
    ) {
        let offsets = |i: usize| self.grid_offsets(if i < count { point(i) } else { usize::MAX });
        for_lanes(
            lanes,
            count,
            |_| 1,
            offsets,
            grid,
            jacs,
            |lane, range, vals, jv| {
                let (v0, j0) = offsets(range.start);
                for i in range {
                    let (vo, jo) = offsets(i);
                    let jac = jac.then(|| &mut jv[jo - j0..]);
                    self.interval_point(d, lane, point(i), &mut vals[vo - v0..], jac);
                }
            },
        );
    }

    /// Offsets in `NodalEval::fgrid` and `NodalEval::fjac` of grid point `gp` (numbered
    /// across the interval constraints, as `fjac_at`); past the last point, the buffers'
    /// lengths.
    pub(super) fn grid_offsets(&self, gp: usize) -> (usize, usize) {
        let mut end = (0, 0);
        for meta in &self.intervals {
            if gp < meta.pt0 + meta.points {
                let i = gp - meta.pt0;
                return (meta.val0 + i * meta.nout, meta.jac0 + i * meta.nnz);
            }
            end = (meta.val0 + meta.points * meta.nout, meta.jac0 + meta.points * meta.nnz);
        }
        end
    }

    /// Grid point `gp`'s interval constraint at `d` with `lane`'s scratch: its values into
    /// `vals` (from the start) and, with `jac`, its Jacobian nonzeros into `jac`.
    pub(super) fn interval_point(
        &self,
        d: &Discretization,
        lane: &mut EvalLane,
        gp: usize,
        vals: &mut [f64],
        jac: Option<&mut [f64]>,
    ) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (stride, pts) = (self.ocp.dynamics.grid_stride(), d.grid_points);
        // The first constraint's points start at 0, so some constraint holds `gp`.
        let c = self.intervals.iter().rposition(|meta| meta.pt0 <= gp).unwrap_or(0);
        let (meta, point) = (&self.intervals[c], gp - self.intervals[c].pt0);
        let base = ((meta.first + point / pts) * pts + point % pts) * stride;
        // The controls are not read (checked in `start`).
        lane.input[..n].copy_from_slice(&d.grid[base..base + n]);
        lane.input[n..n + m].fill(0.0);
        let vals = &mut vals[..meta.nout];
        let jac = jac.map(|j| &mut j[..meta.nnz]);
        let f = &self.ocp.interval_constraints[c].function;
        if f.eval(&lane.input[..n + m], &mut lane.iws[c], vals, jac).is_err() {
            vals.fill(f64::INFINITY);
        }
    }

    /// The evaluation lanes to use: all of them when the settings ask for parallel work, else
    /// the first.
    pub(super) fn eval_lanes<'a>(&self, lanes: &'a mut [EvalLane]) -> &'a mut [EvalLane] {
        let count = if self.settings.discretization.parallel { lanes.len() } else { 1 };
        &mut lanes[..count.max(1)]
    }

    /// The peak of an interval row on `d`'s grid (interval constraints: their values in
    /// `ev.fgrid`): `(sign·x̂ − bound, first grid point of the stencil, its weights)`.
    pub(super) fn peak(
        &self,
        d: &Discretization,
        ev: &NodalEval,
        p: &PeakRow,
    ) -> (f64, usize, Stencil) {
        self.peak_and_vertex(d, ev, p).0
    }

    /// [`peak`](Self::peak) and where it lies ([`Vertex`]; `None` on a grid of fewer than
    /// three points): the segment's peak, or the local one at a fixed grid point.
    pub(super) fn peak_and_vertex(
        &self,
        d: &Discretization,
        ev: &NodalEval,
        p: &PeakRow,
    ) -> ((f64, usize, Stencil), Option<Vertex>) {
        let pts = d.grid_points;
        self.with_row_values(d, ev, p, |g| {
            if pts < 3 {
                let peak = match p.at {
                    Some(j) => local_peak(pts, j, g),
                    None => peak_of(pts, g),
                };
                return (peak, None);
            }
            let v = vertex(pts, p.at, g);
            (bounded_parabola(pts, v.centre, v.theta, &g), Some(v))
        })
    }

    /// `f` of the row's function `j ↦ sign·x_r(t_j) − bound` (a state bound) or `j ↦ g_o(t_j)`
    /// (an interval constraint, from `ev.fgrid`) over the grid points of the row's segment.
    fn with_row_values<R>(
        &self,
        d: &Discretization,
        ev: &NodalEval,
        p: &PeakRow,
        f: impl FnOnce(&dyn Fn(usize) -> f64) -> R,
    ) -> R {
        let pts = d.grid_points;
        match p.of {
            PeakOf::State(r) => {
                let stride = self.ocp.dynamics.grid_stride();
                let base = p.seg * pts * stride + r;
                f(&|j| p.sign * d.grid[base + j * stride] - p.bound)
            }
            PeakOf::Function { c, out } => {
                let meta = &self.intervals[c];
                let v0 = meta.val0 + (p.seg - meta.first) * pts * meta.nout + out;
                f(&|j| ev.fgrid[v0 + j * meta.nout])
            }
        }
    }

    /// Σ w·(positive violation) of the interval-bound peaks at `d` and the largest
    /// violation; each peak's positive violation into `ev.violation` after the nodal ones.
    pub(super) fn eval_peaks(
        &self,
        d: &Discretization,
        ev: &mut NodalEval,
        weights: &[f64],
        at: GridAt,
    ) -> (f64, f64) {
        let nb = self.buffers.len();
        self.eval_interval(d, ev, at);
        let mut max = 0.0f64;
        ev.buffer_violation.fill(0.0);
        for (i, p) in self.peaks.iter().enumerate() {
            let v = self.peak(d, ev, p).0;
            ev.violation[nb + i] = v.max(0.0);
            let worst = &mut ev.buffer_violation[p.buffer];
            *worst = worst.max(v);
            max = max.max(v);
        }
        // Priced as the subproblem prices its buffers: the largest violation of each.
        let sum = ev.buffer_violation.iter().zip(&weights[nb..]).map(|(v, w)| w * v).sum();
        (sum, max)
    }

    /// Propagates the primal point `z = [X | U | S]` (defects only, into `d`) and returns its
    /// merit (see [`merit`](Self::merit)) with the propagation's wall time in ms.
    pub(super) fn evaluate(
        &mut self,
        z: &[f64],
        d: &mut Discretization,
        ev: &mut NodalEval,
        prices: (&[f64], &[f64]),
    ) -> Result<(MeritValues, f64), DiscretizationError> {
        let ms = self.propagate(z, d)?;
        let (u0, s0, vp0, _) = self.layout();
        let (x, u, s) = (&z[..u0], &z[u0..s0], &z[s0..vp0]);
        Ok((self.merit(x, u, s, d, ev, prices, GridAt::Other), ms))
    }

    /// Propagates the primal point `z = [X | U | S]` (defects only, into `d`); the wall time
    /// in ms.
    pub(super) fn propagate(
        &mut self,
        z: &[f64],
        d: &mut Discretization,
    ) -> Result<f64, DiscretizationError> {
        let (u0, s0, vp0, _) = self.layout();
        let (x, u, s) = (&z[..u0], &z[u0..s0], &z[s0..vp0]);
        let t = Instant::now();
        self.ocp.dynamics.defects(x, u, s, &self.settings.discretization, &mut self.dws, d)?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }

    /// The full discretization (with the state-transition matrices) at `z` into `d`; its
    /// wall time in ms.
    pub(super) fn linearize(
        &mut self,
        z: &[f64],
        d: &mut Discretization,
    ) -> Result<f64, DiscretizationError> {
        let (u0, s0, vp0, _) = self.layout();
        let (x, u, s) = (&z[..u0], &z[u0..s0], &z[s0..vp0]);
        let t = Instant::now();
        self.ocp.dynamics.discretize(x, u, s, &self.settings.discretization, &mut self.dws, d)?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }
}
