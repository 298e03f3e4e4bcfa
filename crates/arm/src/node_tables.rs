//! The node tables of a solved arm trajectory (`time`, `angle`, `velocity`, `torque`),
//! read by name and checked once for the readers that need them (mesh refinement,
//! retiming).

use std::collections::BTreeMap;

type Table = Vec<Vec<f64>>;

/// A solved arm trajectory's node tables.
pub(crate) struct NodeTables<'a> {
    pub(crate) times: Vec<f64>,
    pub(crate) q: &'a Table,
    pub(crate) v: &'a Table,
    pub(crate) u: &'a Table,
    /// The torques where each segment ends (N − 1 rows): the next node's, or a solution's
    /// `control_ends` (time-scaled torques jump at the nodes).
    pub(crate) u_end: Table,
}

impl<'a> NodeTables<'a> {
    /// The `time`, `angle`, `velocity` and `torque` tables of `tables` (a solution's or an
    /// iterate's node tables), checked for shape (`n` joints, two nodes or more, increasing
    /// finite times, finite values), with the torques where each segment ends from `ends`
    /// (a solution's `control_ends`; `None`: each next node's).
    pub(crate) fn new(
        tables: &'a BTreeMap<String, Table>,
        ends: Option<&BTreeMap<String, Table>>,
        n: usize,
    ) -> Result<Self, String> {
        let table = |t: &'a BTreeMap<String, Table>, name: &str| {
            t.get(name).ok_or_else(|| format!("the solution has no \"{name}\" node table"))
        };
        let times: Vec<f64> =
            table(tables, "time")?.iter().filter_map(|r| r.first().copied()).collect();
        let (q, v, u) =
            (table(tables, "angle")?, table(tables, "velocity")?, table(tables, "torque")?);
        let fits = |t: &Table| t.len() == times.len() && t.iter().all(|r| r.len() == n);
        if times.len() < 2 || !(fits(q) && fits(v) && fits(u)) {
            return Err(format!("the solution's node tables do not fit {n} joints and 2+ nodes"));
        }
        // Finite first, so that the comparison below is an order.
        if !times.iter().all(|t| t.is_finite()) || times.windows(2).any(|w| w[1] <= w[0]) {
            return Err("the solution's node times do not increase".into());
        }
        let finite = |t: &Table| t.iter().flatten().all(|x| x.is_finite());
        if !(finite(q) && finite(v) && finite(u)) {
            return Err("the solution's node tables hold a non-finite value".into());
        }
        let u_end = match ends.and_then(|e| e.get("torque")) {
            Some(e) if e.len() + 1 == times.len() && e.iter().all(|r| r.len() == n) => {
                if !finite(e) {
                    return Err("the solution's segment-end torques hold a non-finite value".into());
                }
                e.clone()
            }
            Some(_) => {
                return Err(format!(
                    "the solution's segment-end torques do not fit {n} joints and its nodes"
                ));
            }
            None => u[1..].to_vec(),
        };
        Ok(NodeTables { times, q, v, u, u_end })
    }

    /// Whether the first and last nodes are at rest (velocities within 1e-6 rad/s).
    pub(crate) fn at_rest(&self) -> bool {
        let still = |v: &[f64]| v.iter().all(|x| x.abs() <= 1e-6);
        still(&self.v[0]) && still(&self.v[self.v.len() - 1])
    }
}
