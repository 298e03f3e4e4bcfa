//! Fill-reducing orderings of the reduced KKT matrix that follow a multistage problem's
//! stages.
//!
//! QDLDL's approximate minimum degree (AMD) sees only the graph. On a trajectory
//! optimization's KKT matrix it interleaves the nodes of the horizon, and its factor does
//! more work than one that sweeps the horizon from its end: on the seed arm's subproblems a
//! minimum degree constrained to eliminate stage by stage, last stage first, needs 31 % less
//! arithmetic than AMD (plain) and 25 % less (with the collision rows). Whether a row that
//! links stages k and k + 1 is best eliminated with k or with k + 1 depends on the problem
//! (k for the plain seed, k + 1 with the collision rows; the other choice costs 7–52 % more
//! than AMD), so [`staged_orderings`] runs both and keeps the cheaper, which the caller
//! weighs against AMD. What decides it is whether K couples consecutive stages directly (a peak row
//! over a segment's states and both its controls, folded into K, does): where only some
//! segments are coupled so (PTR switches far segments' peak rows off), a mixed sweep takes
//! the greatest stage there and the least elsewhere, and is then the only one run — on the
//! seed's collision variant with peak rows on one segment, 146 thousand multiply-adds
//! against 165 (least) and 182 (greatest), and a re-analysis reorders in about 4 ms
//! instead of 5–10. Forward sweeps (first stage first) never beat the best of these on the
//! seed's four variants or the double integrator, and are not offered.
//!
//! ```text
//! stage(v) = the caller's stage of a primal column, else the least (or greatest, or mixed)
//!            stage of its graph neighbours, propagated outwards from the staged columns;
//! repeatedly eliminate, among the alive nodes of greatest stage, one of least degree (ties:
//! lowest index), and join its neighbours into a clique.
//! ```
//!
//! Nodes from `last` on (the reduced KKT's dense rows, which touch every stage) are
//! eliminated after all others, whatever their stage: eliminated earlier, each would join
//! all its neighbours into one clique.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The staged candidate orderings (`perm[new] = old`) of the symmetric pattern whose upper
/// triangle is `(colptr, rowval)`, given the stage of some of its first `stages.len()`
/// columns: backward sweeps, with unstaged nodes taking the least or the greatest stage of
/// their neighbours — or, when only some consecutive stages are coupled directly (see
/// [`Assign::Mixed`]), the one sweep that takes the greatest where they are and the least
/// elsewhere. Nodes from `last` on come after all others. Of the sweeps, only the cheapest
/// that needs less arithmetic than `than` is returned (none if no sweep does): each counts
/// its factor work as it goes, so the caller's symbolic factorization runs once.
pub(super) fn staged_orderings(
    colptr: &[usize],
    rowval: &[usize],
    stages: &[Option<usize>],
    last: usize,
    than: usize,
) -> Vec<Vec<usize>> {
    let adj = adjacency(colptr, rowval);
    let coupled = coupled_stages(&adj, stages);
    // The work of the cheapest sweep finished so far: a sweep that exceeds it cannot win.
    let best = AtomicUsize::new(usize::MAX);
    let sweep = |assign: Assign| {
        let stage = propagate(&adj, stages, assign, &coupled);
        let key: Vec<i64> = stage
            .iter()
            .enumerate()
            .map(|(v, &s)| if v < last { -(s as i64) } else { i64::MAX })
            .collect();
        let (order, work) = staged_minimum_degree(&adj, &key, than, &best)?;
        best.fetch_min(work, Ordering::Relaxed);
        Some((order, work))
    };
    // (The last stage has no next one: it is never coupled, and says nothing.)
    let inner = &coupled[..coupled.len().saturating_sub(1)];
    if inner.contains(&true) && inner.contains(&false) {
        // Some segments coupled, others not: each gets the choice that suits it (on the
        // seed's collision variant 146 thousand multiply-adds against 165 for the least
        // and 182 for the greatest stage), so the other two sweeps are not run — this is
        // the analysis PTR repeats when it switches rows off.
        return sweep(Assign::Mixed).into_iter().map(|(order, _)| order).collect();
    }
    // The two sweeps are independent: one per core (on a 2-core machine this halves the
    // analysis's ordering time).
    let (least, greatest) = rayon::join(|| sweep(Assign::Least), || sweep(Assign::Greatest));
    // The cheaper, the least sweep on a tie (the one a first-minimum search keeps).
    let cheapest = match (least, greatest) {
        (Some(l), Some(g)) => Some(if g.1 < l.1 { g } else { l }),
        (l, g) => l.or(g),
    };
    cheapest.into_iter().map(|(order, _)| order).collect()
}

/// Which stage an unstaged node takes among those of its staged neighbours (least `lo`,
/// greatest `hi`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Assign {
    /// `lo`.
    Least,
    /// `hi`.
    Greatest,
    /// `hi` if stages `lo` and `lo + 1` are coupled directly — more edges between their
    /// staged columns than stage `lo` has columns, as when a row over a segment's states
    /// and both its controls (a peak row) was folded into K — else `lo`.
    Mixed,
}

/// Per stage k: whether stages k and k + 1 are coupled directly (see [`Assign::Mixed`]).
fn coupled_stages(adj: &[Vec<usize>], stages: &[Option<usize>]) -> Vec<bool> {
    let count = stages.iter().flatten().max().map_or(0, |&s| s + 1);
    let (mut columns, mut edges) = (vec![0usize; count], vec![0usize; count]);
    for (v, s) in stages.iter().enumerate() {
        let Some(s) = *s else { continue };
        columns[s] += 1;
        edges[s] +=
            adj[v].iter().filter(|&&w| stages.get(w).copied().flatten() == Some(s + 1)).count();
    }
    edges.iter().zip(&columns).map(|(e, c)| e > c).collect()
}

/// Arithmetic of an up-looking LDLᵀ factorization with these column counts of L (strictly
/// lower): `Σ c(c + 1)/2`.
pub(super) fn factor_work(l_colptr: &[usize]) -> usize {
    l_colptr.windows(2).map(|w| (w[1] - w[0]) * (w[1] - w[0] + 1) / 2).sum()
}

/// Neighbours of each node (sorted, no self loops) of the symmetric pattern.
fn adjacency(colptr: &[usize], rowval: &[usize]) -> Vec<Vec<usize>> {
    let dim = colptr.len() - 1;
    let mut adj = vec![Vec::new(); dim];
    for c in 0..dim {
        for &r in &rowval[colptr[c]..colptr[c + 1]] {
            if r != c {
                adj[r].push(c);
                adj[c].push(r);
            }
        }
    }
    for a in &mut adj {
        a.sort_unstable();
        a.dedup();
    }
    adj
}

/// Every node's stage: the given ones, then in rounds each unstaged node with staged
/// neighbours takes one of their stages (`assign`); nodes never reached take stage 0.
fn propagate(
    adj: &[Vec<usize>],
    given: &[Option<usize>],
    assign: Assign,
    coupled: &[bool],
) -> Vec<usize> {
    let mut stage: Vec<Option<usize>> =
        (0..adj.len()).map(|v| given.get(v).copied().flatten()).collect();
    loop {
        let next: Vec<Option<usize>> = (0..adj.len())
            .map(|v| {
                stage[v].or_else(|| {
                    let known = || adj[v].iter().filter_map(|&w| stage[w]);
                    let (lo, hi) = (known().min()?, known().max()?);
                    Some(match assign {
                        Assign::Least => lo,
                        Assign::Greatest => hi,
                        Assign::Mixed if coupled.get(lo) == Some(&true) => hi,
                        Assign::Mixed => lo,
                    })
                })
            })
            .collect();
        if next == stage {
            return stage.into_iter().map(|s| s.unwrap_or(0)).collect();
        }
        stage = next;
    }
}

/// Minimum degree on the elimination graph, restricted at each step to the alive nodes of
/// least `key` (ties: lowest index), with its [`factor_work`] (each eliminated node's clique
/// is its column of L). The queue holds (key, degree, node) entries and skips the stale
/// ones; neighbour sets are unsorted, merged through a stamp array.
///
/// `None` once the work reaches `than` or exceeds `best` (read as it goes; another sweep
/// may lower it): such an ordering would not be kept, and a sweep that fills in badly costs
/// far more than a good one (on the seed's collision variant one sweep took 85 ms against
/// the other's 5 before this cut).
fn staged_minimum_degree(
    adj: &[Vec<usize>],
    key: &[i64],
    than: usize,
    best: &AtomicUsize,
) -> Option<(Vec<usize>, usize)> {
    let dim = adj.len();
    let mut g: Vec<Vec<usize>> = adj.to_vec();
    let mut queue: BinaryHeap<Reverse<(i64, usize, usize)>> =
        (0..dim).map(|v| Reverse((key[v], g[v].len(), v))).collect();
    let mut alive = vec![true; dim];
    let mut stamp = vec![usize::MAX; dim];
    let mut order = Vec::with_capacity(dim);
    let mut work = 0;
    while let Some(Reverse((_, degree, v))) = queue.pop() {
        if !alive[v] || degree != g[v].len() {
            continue;
        }
        alive[v] = false;
        order.push(v);
        let clique = std::mem::take(&mut g[v]);
        work += clique.len() * (clique.len() + 1) / 2;
        if work >= than || work > best.load(Ordering::Relaxed) {
            return None;
        }
        for &a in &clique {
            // g[a] ← (g[a] ∪ clique) ∖ {a, v}.
            let ga = &mut g[a];
            ga.retain(|&w| w != v);
            for &w in ga.iter() {
                stamp[w] = a;
            }
            stamp[a] = a;
            for &w in &clique {
                if stamp[w] != a {
                    ga.push(w);
                }
            }
            queue.push(Reverse((key[a], ga.len(), a)));
        }
    }
    Some((order, work))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Upper-triangle pattern of a symmetric graph given by its edges (plus the diagonal).
    fn pattern(dim: usize, edges: &[(usize, usize)]) -> (Vec<usize>, Vec<usize>) {
        let mut cols = vec![vec![]; dim];
        for (c, col) in cols.iter_mut().enumerate() {
            col.push(c);
        }
        for &(a, b) in edges {
            cols[a.max(b)].push(a.min(b));
        }
        let (mut colptr, mut rowval) = (vec![0], vec![]);
        for mut col in cols {
            col.sort_unstable();
            rowval.extend(col);
            colptr.push(rowval.len());
        }
        (colptr, rowval)
    }

    /// The unbounded minimum degree's order.
    fn md(adj: &[Vec<usize>], key: &[i64]) -> Vec<usize> {
        staged_minimum_degree(adj, key, usize::MAX, &AtomicUsize::new(usize::MAX)).unwrap().0
    }

    fn is_permutation(p: &[usize], dim: usize) -> bool {
        let mut seen = vec![false; dim];
        p.len() == dim && p.iter().all(|&v| v < dim && !std::mem::replace(&mut seen[v], true))
    }

    /// An arrow (a hub joined to every leaf): minimum degree eliminates the leaves before
    /// the hub, whatever the hub's index (the hub ties with the last leaf at degree 1), so
    /// the factor has no fill.
    #[test]
    fn minimum_degree_eliminates_an_arrows_leaves_first() {
        let edges: Vec<_> = (1..6).map(|leaf| (0, leaf)).collect();
        let (cp, rv) = pattern(6, &edges);
        let order = md(&adjacency(&cp, &rv), &[0; 6]);
        assert!(is_permutation(&order, 6));
        assert!(order[..4].iter().all(|&v| v != 0), "{order:?}");
    }

    /// The work counted as the sweep goes is the factor's (each clique a column of L), and
    /// a sweep stops, with nothing, once it reaches `than` or exceeds another's `best`.
    #[test]
    fn a_sweep_counts_its_work_and_stops_at_the_bound() {
        // A 5-cycle: the first elimination joins its two neighbours (fill 1), leaving a
        // 4-cycle with a chord: columns of 2, 2, 2, 1, 0 entries, work 3 + 3 + 3 + 1 = 10.
        let (cp, rv) = pattern(5, &[(0, 1), (1, 2), (2, 3), (3, 4), (4, 0)]);
        let adj = adjacency(&cp, &rv);
        let unbounded = AtomicUsize::new(usize::MAX);
        let (order, work) = staged_minimum_degree(&adj, &[0; 5], usize::MAX, &unbounded).unwrap();
        assert!(is_permutation(&order, 5));
        assert_eq!(work, 10);
        assert!(staged_minimum_degree(&adj, &[0; 5], 11, &unbounded).is_some());
        assert!(staged_minimum_degree(&adj, &[0; 5], 10, &unbounded).is_none());
        // Another sweep's equal work does not stop this one (a tie keeps both), a lower does.
        assert!(staged_minimum_degree(&adj, &[0; 5], 11, &AtomicUsize::new(10)).is_some());
        assert!(staged_minimum_degree(&adj, &[0; 5], 11, &AtomicUsize::new(9)).is_none());
        // In staged_orderings, a bound below both sweeps' work leaves no candidate.
        let stages = [Some(0), Some(0), Some(1), Some(1), Some(2)];
        assert_eq!(staged_orderings(&cp, &rv, &stages, 5, 10).len(), 0);
        assert!(!staged_orderings(&cp, &rv, &stages, 5, usize::MAX).is_empty());
    }

    /// The stage key overrides degree: stage 1's leaf waits for all of stage 0.
    #[test]
    fn stages_are_eliminated_in_key_order() {
        // A path 0 – 1 – 2 – 3 with stages [1, 0, 0, 1].
        let (cp, rv) = pattern(4, &[(0, 1), (1, 2), (2, 3)]);
        let adj = adjacency(&cp, &rv);
        let order = md(&adj, &[1, 0, 0, 1]);
        assert!(is_permutation(&order, 4));
        assert!(order[..2].iter().all(|v| [1, 2].contains(v)), "{order:?}");
        let backward = md(&adj, &[-1, 0, 0, -1]);
        assert!(backward[..2].iter().all(|v| [0, 3].contains(v)), "{backward:?}");
    }

    /// Unstaged nodes take the least or greatest stage of their neighbours, in rounds: a
    /// node two links away from the staged ones is staged through the first.
    #[test]
    fn stages_propagate_outwards() {
        // 0 (stage 2) – 2 – 1 (stage 5), and 3 hangs off 2; 4 is isolated.
        let (cp, rv) = pattern(5, &[(0, 2), (1, 2), (2, 3)]);
        let adj = adjacency(&cp, &rv);
        let given = [Some(2), Some(5)];
        let none = [false; 6];
        assert_eq!(propagate(&adj, &given, Assign::Least, &none), vec![2, 5, 2, 2, 0]);
        assert_eq!(propagate(&adj, &given, Assign::Greatest, &none), vec![2, 5, 5, 5, 0]);
        // Mixed: the greatest where the least stage is coupled to the next, else the least.
        let mut coupled = none;
        assert_eq!(propagate(&adj, &given, Assign::Mixed, &coupled), vec![2, 5, 2, 2, 0]);
        coupled[2] = true;
        assert_eq!(propagate(&adj, &given, Assign::Mixed, &coupled), vec![2, 5, 5, 5, 0]);
    }

    /// Stages k and k + 1 are coupled when more edges join their staged columns than stage
    /// k has columns; when some consecutive stages are coupled and others are not, the mixed
    /// sweep is the one offered, else the least and the greatest.
    #[test]
    fn coupled_stages_and_the_mixed_sweep() {
        // Stages 0, 1, 2 of two columns each: 0–2 and 1–3 (stages 0–1) plus 0–3 and 1–2
        // make four edges between stages 0 and 1 (coupled); one edge 2–4 between stages 1
        // and 2 (not coupled). Node 6 is an unstaged row joining stages 0 and 1.
        let edges = [(0, 2), (1, 3), (0, 3), (1, 2), (2, 4), (6, 0), (6, 3), (5, 4)];
        let (cp, rv) = pattern(7, &edges);
        let adj = adjacency(&cp, &rv);
        let stages = [Some(0), Some(0), Some(1), Some(1), Some(2), Some(2)];
        assert_eq!(coupled_stages(&adj, &stages), vec![true, false, false]);
        let candidates = staged_orderings(&cp, &rv, &stages, 7, usize::MAX);
        assert_eq!(candidates.len(), 1);
        assert!(is_permutation(&candidates[0], 7));
        // Without the two cross edges no stages are coupled: the least and the greatest.
        let (cp, rv) = pattern(7, &[(0, 2), (1, 3), (2, 4), (6, 0), (6, 3), (5, 4)]);
        assert_eq!(coupled_stages(&adjacency(&cp, &rv), &stages), vec![false, false, false]);
        let candidates = staged_orderings(&cp, &rv, &stages, 7, usize::MAX);
        let adj = adjacency(&cp, &rv);
        let [least, greatest] = [Assign::Least, Assign::Greatest].map(|assign| {
            let stage = propagate(&adj, &stages, assign, &[false; 3]);
            let key: Vec<i64> = stage.iter().map(|&s| -(s as i64)).collect();
            let unbounded = AtomicUsize::new(usize::MAX);
            staged_minimum_degree(&adj, &key, usize::MAX, &unbounded).unwrap()
        });
        // Both sweeps ran; the dearer one is kept unless it was stopped by the cheaper.
        let cheapest = if greatest.1 < least.1 { &greatest.0 } else { &least.0 };
        assert!(candidates.contains(cheapest));
        assert!(candidates.iter().all(|c| *c == least.0 || *c == greatest.0));
    }

    /// Every candidate is a permutation, and the work count is the up-looking one.
    #[test]
    fn candidates_are_permutations_and_work_counts_columns() {
        let edges: Vec<_> = (0..9).map(|v| (v, v + 1)).chain([(0, 5), (2, 7)]).collect();
        let (cp, rv) = pattern(10, &edges);
        let stages: Vec<Option<usize>> = (0..10).map(|v| (v % 3 != 0).then_some(v / 2)).collect();
        let candidates = staged_orderings(&cp, &rv, &stages, 10, usize::MAX);
        assert!((1..=2).contains(&candidates.len()));
        assert!(candidates.iter().all(|p| is_permutation(p, 10)));
        // Columns with 0, 1, 2 and 3 entries below the diagonal.
        assert_eq!(factor_work(&[0, 0, 1, 3, 6]), 1 + 3 + 6);
    }
}
