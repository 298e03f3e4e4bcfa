//! `Ptr::new`: the subproblem pattern, value sources and row bookkeeping, computed once.

use super::*;

impl Ptr {
    /// Checks the problem ([`Ocp::validate`]) and the settings, then builds the solver (the
    /// subproblem pattern is computed here, once).
    ///
    /// # Errors
    /// The first part of the problem or setting that cannot be used.
    pub fn new(ocp: Ocp, settings: PtrSettings) -> Result<Ptr, PtrError> {
        ocp.validate()?;
        settings.validate()?;
        let (n, m, nn) = (ocp.dynamics.n_x(), ocp.dynamics.n_u(), ocp.nodes);
        let v = VarLayout::new(n, m, nn);
        let n_buffers: usize = ocp
            .nodal
            .iter()
            .map(|c| {
                c.nodes.len()
                    * match c.kind {
                        NodalKind::Inequality => c.function.n_outputs(),
                        NodalKind::Ball { .. } => 1,
                    }
            })
            .sum();
        let interval_rows: Vec<usize> =
            ocp.interval_bounds.iter().copied().filter(|&r| r < n).collect();
        let n_peaks = rows::peaks::state_buffers(&ocp, &interval_rows, nn)
            + ocp
                .interval_constraints
                .iter()
                .map(|c| rows::peaks::function_buffers(c, nn))
                .sum::<usize>();
        let n_vars = v.vb0 + n_buffers + n_peaks;
        // Evaluation buffers of the nodal constraints, per (constraint, node).
        let (mut g_offsets, mut nodal_blocks) = (Vec::new(), Vec::new());
        let (mut gv, mut gj) = (0, 0);
        for (ci, c) in ocp.nodal.iter().enumerate() {
            for &k in &c.nodes {
                g_offsets.push((gv, gj));
                nodal_blocks.push((ci, k));
                gv += c.function.n_outputs();
                gj += c.function.jacobian_pattern().nnz();
            }
        }
        // The rows, family by family, cone by cone (see `rows`).
        let tp = ocp.dynamics.transition_pattern();
        let mut cx = Placement {
            v: &v,
            ocp: &ocp,
            tp,
            pts: settings.discretization.substeps + 1,
            g_offsets: &g_offsets,
            interval_rows: &interval_rows,
            n_vars,
            rb: RowBuilder::default(),
            nodal: Default::default(),
            peaks: rows::peaks::PeakPlacement {
                buffer: v.vb0 + n_buffers,
                first_buffer: v.vb0 + n_buffers,
                ..Default::default()
            },
            socs: Vec::new(),
        };
        let mut cone_rows = [0; 3];
        for cone in [Cone::Zero, Cone::Nonnegative, Cone::SecondOrder] {
            let first = cx.rb.row;
            for f in Family::ALL.iter().filter(|f| f.cone() == cone) {
                f.push(&mut cx);
            }
            cone_rows[cone as usize] = cx.rb.row - first;
        }
        let [n_zero, n_nonneg, _] = cone_rows;
        let Placement { rb, nodal, peaks, socs, .. } = cx;
        let RowBuilder { trip, b, row } = rb;
        let (vp0, vb0) = (v.vp0, v.vb0);
        let nodal_rows = nodal.rows;
        let buffers = nodal.buffers;
        let rows::peaks::PeakPlacement {
            peaks, src: peak_src, stride: peak_stride, intervals, ..
        } = peaks;
        let (a_colptr, a_rowval, sources) = compress(trip, n_vars);
        // Evaluation blocks are numbered (constraint, node) in order: the node of each.
        let eval_node: Vec<usize> =
            ocp.nodal.iter().flat_map(|c| c.nodes.iter().copied()).collect();
        let row_elem = row_elements(&v, row, &nodal_rows, &eval_node, &peaks);
        let a = (&a_colptr[..], &a_rowval[..], &sources[..]);
        let mut elements = if settings.quasi_newton || settings.exact_hessian {
            qn_elements(&v, tp, a, &row_elem)
        } else {
            vec![Element { cols: Vec::new(), pidx: Vec::new() }; nn]
        };
        let exact = if settings.exact_hessian {
            curvature::ExactHessian::place(&v, &ocp, &eval_node, &nodal_rows, row, &mut elements)
        } else {
            curvature::ExactHessian::default()
        };
        let (p_colptr, p_rowval, p_diag) = p_pattern(vp0, n_vars, &mut elements);
        let dws = ocp.dynamics.workspace();
        Ok(Ptr {
            ocp,
            settings,
            n_vars,
            a_colptr,
            a_rowval,
            sources,
            b,
            n_zero,
            n_nonneg,
            dws,
            vb0,
            nodal_rows,
            peaks,
            peak_src,
            peak_stride,
            intervals,
            g_offsets,
            nodal_blocks,
            g_len: (gv, gj),
            buffers,
            socs,
            p_colptr,
            p_rowval,
            p_diag,
            elements,
            row_elem,
            exact,
            state: None,
            cost_on: true,
            starting: StartingPrices::default(),
        })
    }
}

/// `A`'s triplets as compressed columns (rows in insertion order within a column): column
/// pointers, row indices and value sources.
fn compress(
    mut trip: Vec<(usize, usize, Source)>,
    n_vars: usize,
) -> (Vec<usize>, Vec<usize>, Vec<Source>) {
    trip.sort_by_key(|t| (t.1, t.0));
    let mut colptr = vec![0; n_vars + 1];
    for t in &trip {
        colptr[t.1 + 1] += 1;
    }
    for c in 0..n_vars {
        colptr[c + 1] += colptr[c];
    }
    (colptr, trip.iter().map(|t| t.0).collect(), trip.iter().map(|t| t.2).collect())
}

/// The quasi-Newton element of each of the `rows` subproblem rows: segment k owns its
/// dynamics rows, the nodal rows at node k and its peak rows (`usize::MAX`: none).
fn row_elements(
    v: &VarLayout,
    rows: usize,
    nodal_rows: &[NodalRow],
    eval_node: &[usize],
    peaks: &[PeakRow],
) -> Vec<usize> {
    let mut row_elem = vec![usize::MAX; rows];
    for (k, re) in row_elem.iter_mut().take((v.nn - 1) * v.n).enumerate() {
        *re = k / v.n;
    }
    for nr in nodal_rows {
        row_elem[nr.row] = eval_node[nr.eval];
    }
    for p in peaks {
        row_elem[p.row] = p.seg;
    }
    row_elem
}

/// Quasi-Newton elements: segment k's columns are those of x_k, u_k, s_k, u_{k+1} with a
/// varying coefficient in one of its rows (a state that only feeds itself, like a CTCS
/// integral, has none). `a` is `A`'s pattern with its value sources.
fn qn_elements(
    v: &VarLayout,
    tp: &armature_symbolic::SparsityPattern,
    (a_colptr, a_rowval, sources): (&[usize], &[usize], &[Source]),
    row_elem: &[usize],
) -> Vec<Element> {
    let (n, m, nn) = (v.n, v.m, v.nn);
    let varying = |k: usize, c: usize| {
        (a_colptr[c]..a_colptr[c + 1]).any(|p| {
            row_elem[a_rowval[p]] == k
                && match sources[p] {
                    Source::Const(_) => false,
                    // A column of A that is only its own diagonal is constant (1).
                    Source::A(i) => {
                        let (r, j) = ((i % (n * n)) / n, i % n);
                        r != j || (0..n).any(|rr| rr != j && tp.contains(rr, j))
                    }
                    _ => true,
                }
        })
    };
    (0..nn)
        .map(|k| {
            let mut cand: Vec<usize> = (v.x(k, 0)..v.x(k + 1, 0))
                .chain(v.u(k, 0)..v.u(k + 1, 0))
                .chain(std::iter::once(v.s(k)))
                .collect();
            if k + 1 < nn {
                cand.extend(v.u(k + 1, 0)..v.u(k + 1, 0) + m);
            }
            let cols = cand.into_iter().filter(|&c| varying(k, c)).collect();
            Element { cols, pidx: Vec::new() }
        })
        .collect()
}

/// `P`'s upper-triangular pattern: every primal diagonal (columns `0..n_primal`) plus each
/// element's upper triangle; fills each element's `pidx`. Column pointers, row indices and
/// the diagonal's positions.
fn p_pattern(
    n_primal: usize,
    n_vars: usize,
    elements: &mut [Element],
) -> (Vec<usize>, Vec<usize>, Vec<usize>) {
    let mut pairs: Vec<(usize, usize)> = (0..n_primal).map(|c| (c, c)).collect();
    for el in elements.iter() {
        for (a, &ca) in el.cols.iter().enumerate() {
            for &cb in &el.cols[a..] {
                pairs.push((ca.min(cb), ca.max(cb)));
            }
        }
    }
    let pattern = crate::sparse::CscPattern::from_entries(n_vars, pairs);
    let find = |r: usize, c: usize| pattern.position(r, c);
    let diag: Vec<usize> = (0..n_primal).map(|c| find(c, c)).collect();
    for el in elements.iter_mut() {
        let d = el.cols.len();
        el.pidx = vec![usize::MAX; d * d];
        for a in 0..d {
            for b in a..d {
                let (ca, cb) = (el.cols[a], el.cols[b]);
                el.pidx[a * d + b] = find(ca.min(cb), ca.max(cb));
            }
        }
    }
    let crate::sparse::CscPattern { colptr, rowval } = pattern;
    (colptr, rowval, diag)
}
