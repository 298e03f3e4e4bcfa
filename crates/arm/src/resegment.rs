//! The same task on another number of nodes per waypoint segment.

use crate::{ArmError, ArmTask, TaskItem};

impl ArmTask {
    /// The same task with `per_segment` intervals between consecutive waypoints: node `k`
    /// of a task whose waypoints sit every `p` nodes becomes node `k·per_segment / p`, and
    /// the waypoints and orientation ranges keep their instants. Unlike
    /// [`subdivided`](Self::subdivided), the factor need not be whole (2 → 3 pieces per
    /// segment), and the integration grid keeps its step length: the RK4 steps per segment
    /// become `⌈substeps·p / per_segment⌉`, so the grid-point rows sit as densely as before
    /// (the decoupled model is linear, and RK4 integrates it exactly at any step count). A
    /// rigid-body task never takes fewer steps per segment than it had
    /// ([`RIGID_BODY_SUBSTEPS`](crate::RIGID_BODY_SUBSTEPS) holds its end at rest; with 20
    /// on the suite's 3-piece segments half its UR5e tasks ended 1e-4 to 3e-4 rad/s from it).
    ///
    /// # Errors
    /// [`TaskItem::Nodes`] for `per_segment = 0` or more nodes than the solver takes, or
    /// waypoints that are not evenly spaced from the first node to the last;
    /// [`TaskItem::Orientation`] for a range that does not start and end on a waypoint's
    /// node.
    ///
    /// # Example
    /// ```
    /// let seed = armature_arm::fixtures::pick_and_place();
    /// assert_eq!((seed.nodes, seed.waypoints[1].node), (16, 3));
    /// assert_eq!(seed.settings.discretization.substeps, 7);
    /// let two = seed.resegmented(2).unwrap();
    /// assert_eq!((two.nodes, two.waypoints[1].node), (11, 2));
    /// assert_eq!(two.settings.discretization.substeps, 11); // ⌈7·3/2⌉
    /// assert!(seed.resegmented(0).is_err());
    /// ```
    pub fn resegmented(&self, per_segment: usize) -> Result<ArmTask, ArmError> {
        let bad = |m: String| ArmError::new(TaskItem::Nodes, m);
        let p = self.waypoint_spacing().ok_or_else(|| {
            bad("the waypoints are not evenly spaced from the first node to the last".into())
        })?;
        if per_segment == 0 {
            return Err(bad("need 1 or more nodes per segment".into()));
        }
        let segments = (self.nodes - 1) / p;
        let nodes = segments.checked_mul(per_segment).map(|n| n + 1);
        let Some(nodes) = nodes.filter(|n| *n <= armature_scvx::MAX_NODES) else {
            let max = armature_scvx::MAX_NODES;
            return Err(bad(format!("{per_segment} per segment: more than {max} nodes")));
        };
        let at = |k: usize| k / p * per_segment;
        let mut t = self.clone();
        t.nodes = nodes;
        for w in &mut t.waypoints {
            w.node = at(w.node);
        }
        for (i, o) in t.orientation.iter_mut().enumerate() {
            if o.first % p != 0 || o.last % p != 0 {
                let m = format!("nodes {}..{} are not waypoints' nodes", o.first, o.last);
                return Err(ArmError::new(TaskItem::Orientation(i), m));
            }
            (o.first, o.last) = (at(o.first), at(o.last));
        }
        let steps = &mut t.settings.discretization.substeps;
        *steps = self.dynamics.steps_when_split(*steps, p, per_segment);
        Ok(t)
    }

    /// The common spacing of the waypoints' nodes, from node 0 to the last node (`None`
    /// when they are not evenly spaced or do not span the nodes).
    fn waypoint_spacing(&self) -> Option<usize> {
        let p = self.waypoints.get(1)?.node;
        let even = p > 0 && self.waypoints.iter().enumerate().all(|(i, w)| w.node == i * p);
        let last = self.waypoints.last().map(|w| w.node);
        (even && last == self.nodes.checked_sub(1)).then_some(p)
    }
}

#[cfg(test)]
mod tests {
    use crate::fixtures;

    #[test]
    fn instants_are_kept_and_the_grid_keeps_its_step() {
        let seed = fixtures::pick_and_place();
        let (p, steps) = (seed.waypoints[1].node, seed.settings.discretization.substeps);
        for m in 1..=5 {
            let t = seed.resegmented(m).unwrap();
            assert_eq!(t.nodes, 5 * m + 1);
            for (a, b) in seed.waypoints.iter().zip(&t.waypoints) {
                // The same fraction of the horizon.
                assert_eq!(a.node * (t.nodes - 1), b.node * (seed.nodes - 1));
            }
            for (a, b) in seed.orientation.iter().zip(&t.orientation) {
                assert_eq!((a.first * m, a.last * m), (b.first * p, b.last * p));
            }
            let got = t.settings.discretization.substeps;
            assert_eq!(got, (steps * p).div_ceil(m), "{m} per segment");
            // Back to the seed's own count: the task itself.
            let back = t.resegmented(p).unwrap();
            assert_eq!((back.nodes, back.waypoints[3].node), (seed.nodes, seed.waypoints[3].node));
        }
        assert_eq!(seed.resegmented(2 * p).unwrap().nodes, seed.subdivided(2).nodes);
    }

    #[test]
    fn a_rigid_body_task_never_takes_longer_steps_or_fewer_per_segment() {
        let ur5e = fixtures::ur5e_rigid_body();
        let steps = ur5e.settings.discretization.substeps;
        assert_eq!(ur5e.resegmented(3).unwrap().settings.discretization.substeps, steps);
        assert_eq!(ur5e.resegmented(1).unwrap().settings.discretization.substeps, 2 * steps);
    }

    #[test]
    fn tasks_it_cannot_restate_are_refused_with_the_item() {
        let seed = fixtures::pick_and_place();
        let mut uneven = seed.clone();
        uneven.waypoints[2].node += 1;
        let e = uneven.resegmented(3).unwrap_err();
        assert_eq!(e.item, crate::TaskItem::Nodes);
        assert!(e.message.contains("evenly spaced"), "{}", e.message);
        let mut short = seed.clone();
        short.nodes += 2;
        assert_eq!(short.resegmented(3).unwrap_err().item, crate::TaskItem::Nodes);
        let mut none = seed.clone();
        none.nodes = 0;
        assert_eq!(none.resegmented(3).unwrap_err().item, crate::TaskItem::Nodes);
        let mut off = seed.clone();
        off.orientation[0].first = 1;
        assert_eq!(off.resegmented(3).unwrap_err().item, crate::TaskItem::Orientation(0));
        assert!(seed.resegmented(0).is_err());
        assert!(seed.resegmented(usize::MAX).is_err());
    }
}
