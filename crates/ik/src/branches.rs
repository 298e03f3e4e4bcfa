//! Branch search: the IK solution at every node chosen so that the joint path, over all
//! keyframes together, takes least time under the velocity limits — no jumps between IK
//! branches where a continuous path exists.

use armature_kinematics::Chain;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use armature_lie::SO3;

use crate::{IkError, IkResult, IkSettings, IkTrajectory, IkWorkspace, Keyframe, Target, solve};

/// Where the joint path starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start<'a> {
    /// At this configuration: node 0 keeps it (its row reports the IK of node 0's target
    /// from it).
    Fixed(&'a [f64]),
    /// Free: node 0's candidates are the IK from this seed and from random configurations.
    Seed(&'a [f64]),
}

/// Settings of [`ik_branch_search`]; every field has a documented default.
#[derive(Debug, Clone, PartialEq)]
pub struct BranchSettings {
    /// Candidates kept per node (the cheapest paths to them). Default 8.
    pub beam: usize,
    /// Random configurations solved from at each keyframe (and at any node none of whose
    /// warm starts converged). Default 16.
    pub samples: usize,
    /// Cost of a node whose IK did not converge, in the units of the travel cost. Default 10.
    pub unconverged_cost: f64,
    /// Candidates closer than this (rad or m, largest joint difference) are one. Default 1e-3.
    pub distinct: f64,
    /// The share of a path's cost that its node-to-node steps carry, in [0, 1]; the rest is
    /// the travel from keyframe to keyframe. Default 0.25.
    ///
    /// A trajectory optimizer is free to move the joints between the keyframes as it likes
    /// (the nodes between them come from a straight line in task space), so the time a
    /// keyframe segment needs is its keyframes' largest joint change, not the sum of its node
    /// steps' largest changes, which charges a path for zigzags the optimizer removes and,
    /// on a redundant arm, can prefer a configuration at a keyframe that moves more joints
    /// farther. The steps keep a share, so a path with a jump between keyframes still costs
    /// more than one without. 1 is the steps alone.
    pub step_share: f64,
}

impl Default for BranchSettings {
    fn default() -> Self {
        BranchSettings {
            beam: 8,
            samples: 16,
            unconverged_cost: 10.0,
            distinct: 1e-3,
            step_share: 0.25,
        }
    }
}

/// One candidate configuration of a node, with the cheapest path to it.
#[derive(Debug, Clone)]
struct Candidate {
    result: IkResult,
    /// Cost of the cheapest path from node 0 to here.
    cost: f64,
    /// That path's candidate at the previous node.
    parent: usize,
    /// That path's configuration at its last keyframe (this one's, at a keyframe).
    anchor: Vec<f64>,
}

/// The travel cost of a step: `max_i w_i |a_i − b_i|` (with `w` the inverse velocity limits,
/// the least time the step takes).
fn travel(a: &[f64], b: &[f64], w: &[f64]) -> f64 {
    a.iter().zip(b).zip(w).map(|((a, b), w)| w * (a - b).abs()).fold(0.0, f64::max)
}

/// IK at every node of the interpolated keyframes (as [`crate::interpolate_targets`]), by a
/// beam search over IK branches: each node's candidates are the solves warm-started from the
/// previous node's candidates (followed by continuation through intermediate targets where
/// the warm start stalls), and at keyframes (or where no warm start converges) also
/// from `search.samples` random in-limit configurations. A path's cost is its travel (the
/// `weights`-weighted largest joint change: with `weights` the inverse velocity limits, the
/// least time a move takes) from keyframe to keyframe, and a share
/// ([`BranchSettings::step_share`]) of its steps' travel from node to node, plus
/// `node_cost(k, q)` at each node plus [`BranchSettings::unconverged_cost`] per unconverged
/// node; each node keeps the
/// `search.beam` cheapest distinct candidates, and the cheapest path through the last node
/// is returned. Where that path's IK failed at a node between keyframes, the node takes the
/// joint interpolation of its converged neighbours instead.
///
/// A keyframe reachable only on another branch is reached by the path that changes branch
/// where it costs least (often at the start, when the start is free), not by a jump at the
/// keyframe itself.
///
/// # Errors
/// As [`crate::interpolate_targets`] and [`solve`]; [`IkError::BadSeed`] for `weights` of
/// the wrong length or not finite and non-negative, or a `step_share` outside [0, 1].
///
/// # Example
/// ```
/// use armature_ik::{BranchSettings, IkSettings, Keyframe, Start, ik_branch_search};
/// use armature_kinematics::robots;
///
/// let chain = robots::ur5e();
/// let keyframes = [
///     Keyframe { node: 0, position: [0.4, -0.2, 0.3], quaternion_wxyz: None },
///     Keyframe { node: 4, position: [0.4, 0.2, 0.3], quaternion_wxyz: None },
/// ];
/// let seed = vec![0.0; 6];
/// let ik = ik_branch_search(
///     &chain, &keyframes, Start::Seed(&seed), &IkSettings::default(),
///     &BranchSettings::default(), &[1.0; 6], &mut |_, _| 0.0,
/// )
/// .unwrap();
/// assert!(ik.all_converged());
/// assert!(ik.max_joint_step < 0.5);
/// ```
pub fn ik_branch_search(
    chain: &Chain,
    keyframes: &[Keyframe],
    start: Start<'_>,
    settings: &IkSettings,
    search: &BranchSettings,
    weights: &[f64],
    node_cost: &mut dyn FnMut(usize, &[f64]) -> f64,
) -> Result<IkTrajectory, IkError> {
    if weights.len() != chain.dof() || weights.iter().any(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(IkError::BadSeed(format!(
            "branch search: need {} finite non-negative weights, got {:?}",
            chain.dof(),
            weights
        )));
    }
    if !(0.0..=1.0).contains(&search.step_share) {
        return Err(IkError::BadSeed(format!(
            "branch search: step_share must lie in [0, 1], got {}",
            search.step_share
        )));
    }
    let targets = crate::interpolate_targets(keyframes)?;
    let is_keyframe = |k: usize| keyframes.iter().any(|f| f.node == k);
    let warm = IkSettings { restarts: 0, ..settings.clone() };
    let mut ws = IkWorkspace::new(chain);
    let mut layers: Vec<Vec<Candidate>> = Vec::with_capacity(targets.len());
    for (k, target) in targets.iter().enumerate() {
        let mut found: Vec<IkResult> = Vec::new();
        match (k, start) {
            (0, Start::Fixed(q)) => {
                let r = solve(chain, target, q, &warm, &mut ws)?;
                found.push(IkResult { q: q.to_vec(), ..r });
            }
            (0, Start::Seed(q)) => found.push(solve(chain, target, q, &warm, &mut ws)?),
            _ => {
                for c in &layers[k - 1] {
                    let from = &targets[k - 1];
                    found.push(continue_branch(
                        chain,
                        (from, target),
                        &c.result.q,
                        &warm,
                        &mut ws,
                    )?);
                }
            }
        }
        let sample = match (k, start) {
            (0, Start::Fixed(_)) => false,
            (0, Start::Seed(_)) => true,
            _ => is_keyframe(k) || found.iter().all(|r| !r.converged),
        };
        if sample {
            found.extend(sampled(chain, target, &warm, search.samples, settings.rng_seed, k)?);
        }
        let previous = if k == 0 { None } else { Some(&layers[k - 1][..]) };
        let node = (k, is_keyframe(k));
        layers.push(best_paths(found, previous, node, search, weights, node_cost));
    }
    let keyframe: Vec<bool> = (0..targets.len()).map(is_keyframe).collect();
    Ok(backtrack(&layers, &keyframe))
}

/// Task-space steps into which [`continue_branch`] divides a node step that a warm start
/// does not converge across.
const CONTINUATION_STEPS: usize = 4;

/// The IK of node target `to` warm-started from the previous node's configuration `q` (the
/// IK of `from`). Where that solve does not converge, the branch is followed by continuation:
/// through `CONTINUATION_STEPS` targets on the way from `from` to `to` (positions on the
/// line, orientations on the geodesic), each solved from the last without the stall rule and
/// with four times the iterations. A warm start that stalls is often a branch whose damped
/// steps are short at first — near a singular or limit-bound configuration — not a branch
/// that ends: on the suite's arm7-ball-21 the branch through the pick was lost this way at
/// the first node after its pre-grasp waypoint (at three and at four nodes per segment), and
/// the path jumped 2–3 rad to another one.
fn continue_branch(
    chain: &Chain,
    (from, to): (&Target, &Target),
    q: &[f64],
    warm: &IkSettings,
    ws: &mut IkWorkspace,
) -> Result<IkResult, IkError> {
    let first = solve(chain, to, q, warm, ws)?;
    if first.converged {
        return Ok(first);
    }
    let patient = IkSettings {
        stall_ratio: 0.0,
        max_iterations: warm.max_iterations.saturating_mul(4),
        ..warm.clone()
    };
    let mut at = q.to_vec();
    let mut last = None;
    for i in 1..=CONTINUATION_STEPS {
        let s = i as f64 / CONTINUATION_STEPS as f64;
        let orientation = match (from.orientation, to.orientation) {
            (Some(a), Some(b)) => Some(SO3::slerp(&a, &b, s)),
            (_, o) => o,
        };
        let step = Target { position: from.position.lerp(&to.position, s), orientation };
        let r = solve(chain, &step, &at, &patient, ws)?;
        if !r.converged {
            return Ok(first);
        }
        at.clone_from(&r.q);
        last = Some(r);
    }
    Ok(last.unwrap_or(first))
}

/// IK of `target` from `count` random in-limit configurations (∩ [−π, π]), in parallel; the
/// converged solutions.
fn sampled(
    chain: &Chain,
    target: &Target,
    warm: &IkSettings,
    count: usize,
    rng_seed: u64,
    node: usize,
) -> Result<Vec<IkResult>, IkError> {
    let (lo, hi) = chain.position_limits();
    let mut rng = Pcg64Mcg::seed_from_u64(rng_seed ^ (node as u64).wrapping_mul(0x9E37_79B9));
    let pi = std::f64::consts::PI;
    let seeds: Vec<Vec<f64>> = (0..count)
        .map(|_| {
            lo.iter().zip(&hi).map(|(l, h)| rng.random_range(l.max(-pi)..=h.min(pi))).collect()
        })
        .collect();
    let solved: Vec<IkResult> = seeds
        .par_iter()
        .map_init(|| IkWorkspace::new(chain), |ws, s| solve(chain, target, s, warm, ws))
        .collect::<Result<_, _>>()?;
    Ok(solved.into_iter().filter(|r| r.converged).collect())
}

/// Each found configuration at node `k` (a keyframe or not) with its cheapest path from the
/// previous node's candidates; the `search.beam` cheapest distinct ones.
fn best_paths(
    found: Vec<IkResult>,
    previous: Option<&[Candidate]>,
    (k, keyframe): (usize, bool),
    search: &BranchSettings,
    weights: &[f64],
    node_cost: &mut dyn FnMut(usize, &[f64]) -> f64,
) -> Vec<Candidate> {
    let share = search.step_share;
    let step_cost = |p: &Candidate, q: &[f64]| {
        let segment = if keyframe { travel(&p.anchor, q, weights) } else { 0.0 };
        p.cost + share * travel(&p.result.q, q, weights) + (1.0 - share) * segment
    };
    let mut all: Vec<Candidate> = found
        .into_iter()
        .map(|result| {
            let own = node_cost(k, &result.q)
                + if result.converged { 0.0 } else { search.unconverged_cost };
            let (cost, parent) = previous.map_or((0.0, 0), |prev| {
                prev.iter()
                    .enumerate()
                    .map(|(i, p)| (step_cost(p, &result.q), i))
                    .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
            });
            let anchor = match previous {
                Some(prev) if !keyframe => prev[parent].anchor.clone(),
                _ => result.q.clone(),
            };
            Candidate { cost: cost + own, parent, result, anchor }
        })
        .collect();
    all.sort_by(|a, b| a.cost.total_cmp(&b.cost));
    let mut kept: Vec<Candidate> = Vec::with_capacity(search.beam);
    for c in all {
        if kept.len() == search.beam.max(1) {
            break;
        }
        if kept.iter().all(|d| largest_difference(&c.result.q, &d.result.q) > search.distinct) {
            kept.push(c);
        }
    }
    kept
}

fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
}

/// The cheapest path through the last node, with each unconverged node between keyframes
/// replaced by the joint interpolation of its nearest converged neighbours.
fn backtrack(layers: &[Vec<Candidate>], keyframe: &[bool]) -> IkTrajectory {
    let mut nodes: Vec<IkResult> = Vec::with_capacity(layers.len());
    let mut at = 0;
    for layer in layers.iter().rev() {
        nodes.push(layer[at].result.clone());
        at = layer[at].parent;
    }
    nodes.reverse();
    let mut q: Vec<Vec<f64>> = nodes.iter().map(|r| r.q.clone()).collect();
    for k in 0..q.len() {
        if nodes[k].converged || keyframe[k] {
            continue;
        }
        let before = (0..k).rev().find(|&i| nodes[i].converged);
        let after = (k + 1..q.len()).find(|&i| nodes[i].converged);
        if let (Some(a), Some(b)) = (before, after) {
            let s = (k - a) as f64 / (b - a) as f64;
            q[k] = q[a].iter().zip(&q[b]).map(|(x, y)| x + s * (y - x)).collect();
        }
    }
    for (r, q) in nodes.iter_mut().zip(&q) {
        r.q.clone_from(q);
    }
    let max_joint_step = q.windows(2).map(|w| largest_difference(&w[0], &w[1])).fold(0.0, f64::max);
    IkTrajectory { q, nodes, max_joint_step }
}
